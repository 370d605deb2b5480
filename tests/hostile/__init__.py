"""Hostile deliveries and profiles (issue 17): see cases.py; run ``python -m tests.hostile``."""

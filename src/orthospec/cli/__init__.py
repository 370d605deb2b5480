"""Thin click commands: parse, call the library, render. Never compute here."""

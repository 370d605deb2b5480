"""Profiles this plugin ships (orthospec finds the YAML files in this folder by id)."""

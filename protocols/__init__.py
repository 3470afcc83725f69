"""Certification procedures and ball tests (each a TOML file here) run by a small runner."""

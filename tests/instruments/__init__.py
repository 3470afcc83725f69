"""Instrument classes, their twins, and what a run records of its instruments."""

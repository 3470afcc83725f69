"""Benchmarks and study harnesses: timing, machine description and the generated study documents.

Not part of the installed package; run the scripts from the repository root (see the Makefile).
"""

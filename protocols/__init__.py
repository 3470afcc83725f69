"""Certification procedures (NCAA BESR, BBCOR, BBS) run by a small runner."""

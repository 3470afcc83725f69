"""Instrument twins: other wire front ends (SCPI, ...) on the same SimWorld as the line devices."""

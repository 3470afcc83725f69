"""Simulated instruments: twins of real instrument classes on local ports over a SimWorld."""

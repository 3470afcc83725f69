"""Simulated instruments: twins of real instrument classes on the same SimWorld, on local TCP ports."""

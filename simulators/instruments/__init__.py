"""Simulated instruments: twins of real instrument classes, other wire front ends on the same SimWorld
as the line devices, on local TCP ports."""

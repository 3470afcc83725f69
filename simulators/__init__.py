"""Simulated hardware that speaks the devices' wire formats, driven by a physics scene."""

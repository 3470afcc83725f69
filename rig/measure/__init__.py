"""Measurement maths: gate timestamps to speeds, metrics, uncertainty, shot validity. Pure."""

from rig.measure.speeds import GatePasses, ShotSpeeds, shot_speeds, split_passes

__all__ = ["GatePasses", "ShotSpeeds", "shot_speeds", "split_passes"]

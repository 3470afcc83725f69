"""Real device drivers (air cannon, light gates, pivot clamp) over serial."""

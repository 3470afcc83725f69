"""The air cannon: pressure, arm, fire, vent, interlocks."""

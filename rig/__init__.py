"""Controller software for a bat-certification air-cannon rig."""

__version__ = "0.1.0"

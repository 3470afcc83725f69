"""The three light gates and their counter-timer."""

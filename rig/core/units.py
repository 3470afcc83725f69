"""Unit conversions to SI. Everything inside the controller is SI."""

MPH = 0.44704  # m/s per mile per hour
INCH = 0.0254  # m per inch
OUNCE = 0.028349523125  # kg per avoirdupois ounce
G_STANDARD = 9.80665  # m/s^2

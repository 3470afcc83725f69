"""What a calibration needs of its population: plain numbers, importable without the model."""

# Where the ball strikes when a row gives no location_in: the middle of 6.0-7.0 in from the barrel
# end, where the BBCOR procedure's scan finds its maximum on most bats.
DEFAULT_LOCATION_IN = 6.5
MIN_BATS = 8
MIN_HOOP_SPAN_HZ = 400.0  # a span narrower than this cannot separate m2 from c2

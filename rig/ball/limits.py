"""What a ball fit needs of its design: plain numbers, importable without the model (the CLI's help)."""

MIN_SPEEDS = 5  # distinct inbound speeds, as the paper's test
SPEED_GROUP_M_S = 1.0  # speeds closer than this to the next one count as one speed
MIN_SPEED_RATIO = 2.0  # highest / lowest speed: below it a and b are not separated (docs/ball.md)
MAX_POINTS = 2000  # a lab's CCOR test has tens to hundreds; more is not a test but a hostile file
MAX_FOLDS = 50  # more balls (or points) than this: leave one fold of them out at a time

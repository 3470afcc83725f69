"""The built-in ball tests' names (each is protocols/<name>.toml): a light module, so that the
command line's help lists them without loading the procedures."""

BALL_BUILTIN = ("ccor", "ball-cor", "ball-cor-fastpitch")

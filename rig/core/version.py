"""The software's version, on the lowest floor: every record names it, and no floor needs the
package's facade (`import rig`) to say which software wrote a record. pyproject.toml holds the same."""

__version__ = "0.1.0"


def software() -> dict[str, str]:
    """What a run records as the software that made it (RunStarted's `software`)."""
    import platform  # here, not at import: `import rig` (every command's start) loads this module

    return {"rig": __version__, "python": platform.python_version()}

"""The software's version, on the lowest floor: every record names it, and no floor needs the
package's facade (`import rig`) to say which software wrote a record. pyproject.toml holds the same."""

__version__ = "0.1.0"

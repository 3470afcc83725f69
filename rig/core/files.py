"""Reading a whole file a user names, refused in one line when it cannot be what it claims to be."""

from __future__ import annotations

from pathlib import Path

from rig.core.errors import ConfigError


def read_bounded(path: str | Path, max_bytes: int, what: str) -> bytes:
    """The file's bytes; ConfigError naming the file if it is missing, a directory, larger than
    `max_bytes` (a hostile or wrong file is not read into memory) or binary (it holds NUL bytes).
    `what` names what the file should be, e.g. "a ball file"."""
    path = Path(path)
    try:
        if path.is_file() and path.stat().st_size > max_bytes:
            raise ConfigError(f"not {what}: larger than {max_bytes} bytes", source=str(path))
        raw = path.read_bytes()
    except FileNotFoundError:
        raise ConfigError("no such file", source=str(path)) from None
    except IsADirectoryError:
        raise ConfigError(f"not {what}: a directory", source=str(path)) from None
    if b"\x00" in raw:
        raise ConfigError(f"not {what}: it holds NUL bytes", source=str(path))
    return raw

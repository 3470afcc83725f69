"""Reading a file a user names, refused in one line when it cannot be what it claims to be.

Every input file goes through here: its size is bounded whatever it is (a regular file by its
size, a device or a FIFO by reading at most one byte more than the bound), a directory or a NUL
byte is refused, and parsed TOML or JSON may be nested at most MAX_DEPTH levels (a deeper file
would crash the parser, or whatever walks the data after it, by recursion). Each refusal is a
ConfigError naming the file.
"""

from __future__ import annotations

import json
import math
import os
import stat
import tomllib
from pathlib import Path
from typing import Any

from rig.core.errors import ConfigError, shown

MAX_DEPTH = 32  # tables, arrays or objects inside each other; the deepest file we write has 4
CONFIG_BYTES = 1_000_000  # a bat, procedure, rig config, scene or lot file is a few kB
DATA_BYTES = 64_000_000  # a population or a calibration: about 300 bytes a bat
CHUNK = 1 << 20


def read_bounded(
    path: str | Path, max_bytes: int, what: str, missing: str = "no such file", binary: bool = False
) -> bytes:
    """The file's bytes; ConfigError naming the file if it is missing, a directory, larger than
    `max_bytes` (a hostile or wrong file is not read into memory; an endless one, /dev/zero or a
    FIFO, is read no further) or, unless `binary`, holds NUL bytes. `what` names what the file
    should be, e.g. "a ball file"; `missing` is the reason given for a file that does not exist."""
    source = str(path)
    try:
        # non-blocking open: a FIFO nobody writes reads as empty rather than waiting for ever
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except (FileNotFoundError, NotADirectoryError):
        raise ConfigError(missing, source=source) from None
    except OSError as exc:
        raise ConfigError(f"cannot read it: {exc.strerror or exc}", source=source) from None
    try:
        raw = _read_fd(fd, max_bytes, what, source)
    finally:
        os.close(fd)
    if not binary and b"\x00" in raw:
        raise ConfigError(f"not {what}: it holds NUL bytes", source=source)
    return raw


def _read_fd(fd: int, max_bytes: int, what: str, source: str) -> bytes:
    """At most `max_bytes` bytes of an open file; ConfigError if there are more."""
    mode = os.fstat(fd)
    if stat.S_ISDIR(mode.st_mode):
        raise ConfigError(f"not {what}: a directory", source=source)
    regular = stat.S_ISREG(mode.st_mode)
    if regular and mode.st_size > max_bytes:
        raise ConfigError(f"not {what}: larger than {max_bytes} bytes", source=source)
    os.set_blocking(fd, True)
    chunks: list[bytes] = []
    total = 0
    try:
        while total <= max_bytes:
            chunk = os.read(fd, min(CHUNK, max_bytes + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
    except OSError as exc:
        raise ConfigError(f"cannot read it: {exc.strerror or exc}", source=source) from None
    if total > max_bytes:
        endless = "" if regular else " (a device or a FIFO that does not end)"
        raise ConfigError(f"not {what}: larger than {max_bytes} bytes{endless}", source=source)
    return b"".join(chunks)


def read_text(
    path: str | Path, max_bytes: int, what: str, encoding: str = "utf-8", missing: str = "no such file"
) -> str:
    """The file as text (read_bounded, then decoded); ConfigError if it is not UTF-8."""
    raw = read_bounded(path, max_bytes, what, missing=missing)
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not {what}: not UTF-8 text (byte {exc.start})", source=str(path)) from None


def parse_toml(text: str, source: str, what: str = "a TOML file") -> dict[str, Any]:
    """Parsed TOML, nested at most MAX_DEPTH levels; ConfigError naming `source` otherwise."""
    try:
        data = tomllib.loads(text)
    except RecursionError:
        raise _too_deep(source, what) from None
    except ValueError as exc:  # TOMLDecodeError; an integer of more digits than Python converts
        raise ConfigError(f"not valid TOML: {_first_line(exc)}", source=source) from None
    check_nesting(data, source, what)
    return data


def parse_json(text: str | bytes, source: str, what: str = "a JSON file") -> Any:
    """Parsed JSON, nested at most MAX_DEPTH levels; ConfigError naming `source` otherwise."""
    try:
        data = json.loads(text)
    except RecursionError:
        raise _too_deep(source, what) from None
    except (ValueError, UnicodeDecodeError) as exc:  # JSONDecodeError; too many digits; not UTF-8
        raise ConfigError(f"not {what}: {_first_line(exc)}", source=source) from None
    check_nesting(data, source, what)
    return data


def read_toml_file(
    path: str | Path, max_bytes: int, what: str, missing: str = "no such file"
) -> dict[str, Any]:
    """A TOML file read within `max_bytes` and parsed (read_text, parse_toml)."""
    return parse_toml(read_text(path, max_bytes, what, missing=missing), str(path), what)


def read_json_file(path: str | Path, max_bytes: int, what: str) -> tuple[Any, bytes]:
    """A JSON file read within `max_bytes` and parsed, and the bytes it was parsed from."""
    raw = read_bounded(path, max_bytes, what)
    return parse_json(raw, str(path), what), raw


def number_cell(cell: str, column: str, where: str) -> float:
    """A data file's cell as a finite float; ConfigError naming `where` and the column otherwise."""
    try:
        x = float(cell)
    except ValueError:
        raise ConfigError(f"{column} {shown(cell)} is not a number", source=where) from None
    if not math.isfinite(x):
        raise ConfigError(f"{column} {shown(cell)} is not a finite number", source=where)
    return x


def check_nesting(data: Any, source: str, what: str, limit: int = MAX_DEPTH) -> None:
    """ConfigError if dicts and lists sit more than `limit` levels inside each other (no recursion)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, dict):
            children = list(value.values())
        elif isinstance(value, list):
            children = value
        else:
            continue
        if depth > limit:
            raise _too_deep(source, what, limit)
        stack.extend((child, depth + 1) for child in children)


def _too_deep(source: str, what: str, limit: int = MAX_DEPTH) -> ConfigError:
    return ConfigError(f"not {what}: nested more than {limit} levels deep", source=source)


def _first_line(exc: Exception) -> str:
    text = str(exc)
    return text.splitlines()[0] if text else type(exc).__name__

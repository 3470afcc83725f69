"""Reading TOML files into validated models, with errors that name the file and the field."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from rig.core.errors import ConfigError
from rig.core.files import CONFIG_BYTES, read_toml_file

M = TypeVar("M", bound=BaseModel)


def read_toml(
    path: str | Path, missing: str = "no such file", what: str = "a TOML file", max_bytes: int = CONFIG_BYTES
) -> dict[str, Any]:
    """The parsed file; ConfigError naming the file if it is missing, larger than `max_bytes`,
    not UTF-8, not TOML or nested too deeply (rig.core.files)."""
    return read_toml_file(path, max_bytes, what, missing=missing)


def validate(model: type[M], data: Any, source: str, prefix: str = "") -> M:
    """Validate `data` as `model`; the first error becomes a ConfigError naming source and field."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "(top level)"
        raise ConfigError(first["msg"], source=source, field=f"{prefix}{where}") from None


def table(data: dict[str, Any], name: str, source: str) -> dict[str, Any]:
    """The [name] table of a parsed file, or a ConfigError saying it is missing."""
    found = data.get(name)
    if not isinstance(found, dict):
        raise ConfigError(f"needs a [{name}] table", source=source)
    return found


Scalar = str | int | float | bool


def dump_toml(data: dict[str, Any]) -> str:
    """`data` as TOML text that tomllib reads back equal: tables of scalars, lists of scalars and
    inline tables (a driver's options); None values are left out. A value TOML cannot hold (NaN,
    an infinite number, another type) is a ValueError naming its key."""
    lines: list[str] = []
    _table(data, (), lines)
    return "\n".join(lines).lstrip("\n") + "\n"


def _table(data: dict[str, Any], path: tuple[str, ...], lines: list[str]) -> None:
    plain = {k: v for k, v in data.items() if (v is not None and not isinstance(v, dict)) or _inline(k, v)}
    nested = {k: v for k, v in data.items() if isinstance(v, dict) and k not in plain}
    if path and (plain or not nested):
        lines += ["", "[" + ".".join(map(_key, path)) + "]"]
    lines += [f"{_key(k)} = {_value(v, (*path, k))}" for k, v in plain.items()]
    for key, value in nested.items():
        _table(value, (*path, key), lines)


def _inline(key: str, value: Any) -> bool:
    """A table written inline: a driver's `options` (scalars and lists)."""
    return isinstance(value, dict) and key == "options"


def _key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else _string(key)


def _string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    escaped = "".join(c if c >= " " and c != "\x7f" else f"\\u{ord(c):04x}" for c in escaped)
    return f'"{escaped}"'


def _value(value: Any, path: tuple[str, ...]) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"{'.'.join(path)}: {value} cannot be written to TOML")
        return repr(value)
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_value(v, path) for v in value) + "]"
    if isinstance(value, dict):
        return (
            "{"
            + ", ".join(f"{_key(k)} = {_value(v, (*path, k))}" for k, v in value.items() if v is not None)
            + "}"
        )
    raise ValueError(f"{'.'.join(path)}: a {type(value).__name__} cannot be written to TOML")

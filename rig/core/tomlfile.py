"""Reading TOML files into validated models, with errors that name the file and the field."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from rig.core.errors import ConfigError

M = TypeVar("M", bound=BaseModel)


def read_toml(path: str | Path, missing: str = "no such file") -> dict[str, Any]:
    """The parsed file; a missing file or bad TOML raises ConfigError naming the file."""
    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(missing, source=str(path)) from None
    except (UnicodeDecodeError, IsADirectoryError) as exc:
        raise ConfigError(f"not a readable text file: {exc}", source=str(path)) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", source=str(path)) from None


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

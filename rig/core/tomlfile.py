"""Reading TOML files into validated models, with errors that name the file and the field."""

from __future__ import annotations

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

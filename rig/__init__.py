"""Controller software for a bat-certification air-cannon rig.

`import rig` gives the public Python API (docs/api.md): `open_store`, `Bat`, `simulated`,
`from_config`, `certify`, `Result`, `Verdict`, `RigSpec`, `RunControl` and `RigError`, and
`rig.plans` for composing a lab's own procedure from the standard steps. They load on
first use, so that `import rig` (the CLI's start-up) stays light: no pydantic, numpy or drivers.
Type checkers read their types from __init__.pyi; import-linter sees no import of rig.api here.
"""

from __future__ import annotations

import importlib

from rig.core.version import __version__

_API = (
    "Bat",
    "Result",
    "RigSpec",
    "RunControl",
    "Verdict",
    "certify",
    "from_config",
    "open_store",
    "simulated",
)
__all__ = [
    "Bat",
    "Result",
    "RigError",
    "RigSpec",
    "RunControl",
    "Verdict",
    "__version__",
    "certify",
    "from_config",
    "open_store",
    "plans",
    "simulated",
]


def __getattr__(name: str) -> object:
    """Load a public name on first use (PEP 562)."""
    if name == "RigError":
        return importlib.import_module("rig.core.errors").RigError
    if name in _API:
        return getattr(importlib.import_module("rig.api"), name)
    if name == "plans":
        return importlib.import_module("rig.plans")
    raise AttributeError(f"module 'rig' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})

"""How the kernel's one source is run: compiled by numba, or by the interpreter as plain Python.

`rig.physics._dop853` asks `numba_or_plain(__name__)` for its `nb`: under its own name it gets numba
(compiled, cached on disk); loaded again under another name (`_interpreted`) it gets decorators that
return each function unchanged and `range` for `prange`, without importing numba (about a second).
The source is the same file, executed as it is; nothing is edited. `check_digest` holds the model
that file inlines (`_kernel_model`) to the text pinned in it, which numba's cache sees.
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from types import ModuleType, SimpleNamespace
from typing import Any

COMPILED = "rig.physics._dop853"


def _njit(*args: Any, **kwargs: Any) -> Any:
    """numba.njit's signature, doing nothing: @_njit and @_njit(cache=True, ...) both give f back."""
    if len(args) == 1 and callable(args[0]) and not kwargs:
        return args[0]
    return lambda func: func


PLAIN = SimpleNamespace(njit=_njit, prange=range)


def numba_or_plain(module_name: str) -> ModuleType | SimpleNamespace:
    """numba for the compiled kernel module, the plain stand-ins for any other name."""
    if module_name == COMPILED:
        import numba

        return numba
    return PLAIN


def source_digest(module: ModuleType) -> str:
    """sha256 of a module's source text, read with universal newlines (a CRLF checkout reads the same)."""
    if module.__file__ is None:
        raise ImportError(f"{module.__name__} has no source file to pin")
    text = Path(module.__file__).read_text(encoding="utf-8")
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def check_digest(module: ModuleType, pinned: str, pinned_in: str) -> None:
    """ImportError unless `module`'s source is the text pinned in file `pinned_in` (_dop853.MODEL_DIGEST)."""
    found = source_digest(module)
    if found != pinned:
        raise ImportError(
            f"{module.__name__} changed since {pinned_in} pinned it: set MODEL_DIGEST there to {found!r}"
            f" (numba keys the compiled kernel's cache on the text of {pinned_in} only)"
        )

"""How the kernel's one source is run: compiled by numba, or by the interpreter as plain Python.

`rig.physics._dop853` asks `numba_or_plain(__name__)` for its `nb`: under its own name it gets numba
(compiled, cached on disk); loaded again under another name (`_interpreted`) it gets decorators that
return each function unchanged and `range` for `prange`, without importing numba (about a second).
The source is the same file, executed as it is; nothing is edited.
"""

from __future__ import annotations

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

"""The compiled kernel's own source (`_dop853`), run by the interpreter: the same arithmetic, no numba.

Loading numba and the cached machine code costs about a second; one collision solved by the
interpreter costs 10-20 ms. So a process that asks for a few single solves (`rig model cor`, a
certificate's cross-check) gets its answer before numba would have loaded; `fast` switches to the
compiled kernel once enough solves have been asked for, and for every batch. The source is read,
not copied: the one line `import numba as nb` is swapped for decorators that return the function
unchanged, and `nb.prange` becomes `range`.
"""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType, SimpleNamespace
from typing import Any

_SOURCE_MODULE = "rig.physics._dop853"
_NAME = "rig.physics._dop853_interpreted"
_IMPORT = "import numba as nb\n"


def _njit(*args: Any, **kwargs: Any) -> Any:
    """numba.njit's signature, doing nothing: @_njit and @_njit(cache=True, ...) both give f back."""
    if len(args) == 1 and callable(args[0]) and not kwargs:
        return args[0]
    return lambda func: func


def load() -> ModuleType:
    """The kernel module run by the interpreter (loaded once a process)."""
    if _NAME in sys.modules:
        return sys.modules[_NAME]
    spec = importlib.util.find_spec(_SOURCE_MODULE)
    if spec is None or spec.origin is None:
        raise ImportError(f"cannot find {_SOURCE_MODULE}")
    with open(spec.origin, encoding="utf-8") as f:
        source = f.read()
    if source.count(_IMPORT) != 1:
        raise ImportError(f"{spec.origin} must import numba exactly once as {_IMPORT.strip()!r}")
    module = ModuleType(_NAME)
    module.__file__ = spec.origin
    module.__dict__["_nb_shim"] = SimpleNamespace(njit=_njit, prange=range)
    code = compile(source.replace(_IMPORT, "nb = _nb_shim\n"), spec.origin, "exec")
    sys.modules[_NAME] = module
    try:
        exec(code, module.__dict__)
    except BaseException:
        del sys.modules[_NAME]
        raise
    return module

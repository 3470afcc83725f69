"""The compiled kernel's own source (`_dop853`), run by the interpreter: the same arithmetic, no numba.

Loading numba and the cached machine code costs about a second; one collision solved by the
interpreter costs 10-20 ms. So a process that asks for a few single solves (`rig model cor`, a
certificate's cross-check) gets its answer before numba would have loaded; `fast` switches to the
compiled kernel once enough solves have been asked for, and for every batch. The file is loaded a
second time under another module name, as it is: its `nb` then comes from `_jit.numba_or_plain` as
decorators that return each function unchanged and `range` for `prange`; so the model it integrates
is `_kernel_model`'s functions themselves, the very objects the compiled kernel compiles.
"""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType

from rig.physics._jit import COMPILED

_NAME = "rig.physics._dop853_interpreted"


def load() -> ModuleType:
    """The kernel module run by the interpreter (loaded once a process)."""
    if _NAME in sys.modules:
        return sys.modules[_NAME]
    found = importlib.util.find_spec(COMPILED)
    if found is None or found.origin is None:
        raise ImportError(f"cannot find {COMPILED}")
    spec = importlib.util.spec_from_file_location(_NAME, found.origin)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {found.origin} as {_NAME}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[_NAME] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[_NAME]
        raise
    return module

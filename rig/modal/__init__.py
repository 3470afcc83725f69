"""Modal analysis of impact tests: the bat's hoop and bending frequencies from hammer and accelerometers.

Pure numpy/scipy (pyuff for Universal Files); imports nothing of ours but rig.core.
See docs/modal.md for the formats, the method and the diagnosis rules. The names load on first
use: `rig.modal.link` (what certify needs) does not bring in the analysis and scipy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rig.core.lazy import lazy_names

# Eager (numpy only): the function `simulate` shares its name with its module, and a lazy name
# would be shadowed by the module once anything imports rig.modal.simulate.
from rig.modal.simulate import SimMode, SimSettings, bat_modes, simulate

if TYPE_CHECKING:
    from rig.modal.analysis import ModalResult, ModalSettings, Mode, analyze
    from rig.modal.errors import (
        ClippedSignal,
        DoubleHit,
        FlatChannel,
        LowCoherence,
        ModalError,
        NoHits,
        NoHoopMode,
        RecordingFormatError,
        RecordTooShort,
        WeakHit,
    )
    from rig.modal.link import MODAL_RESULT_KIND, latest_modal_result, record_modal_result, with_measured_hoop
    from rig.modal.read import read_recording
    from rig.modal.recording import CSV_HEADER, Recording, read_csv, write_csv

_WHERE = {
    "ModalResult": "analysis",
    "ModalSettings": "analysis",
    "Mode": "analysis",
    "analyze": "analysis",
    "ClippedSignal": "errors",
    "DoubleHit": "errors",
    "FlatChannel": "errors",
    "LowCoherence": "errors",
    "ModalError": "errors",
    "NoHits": "errors",
    "NoHoopMode": "errors",
    "RecordingFormatError": "errors",
    "RecordTooShort": "errors",
    "WeakHit": "errors",
    "MODAL_RESULT_KIND": "link",
    "latest_modal_result": "link",
    "record_modal_result": "link",
    "with_measured_hoop": "link",
    "CSV_HEADER": "recording",
    "Recording": "recording",
    "read_csv": "recording",
    "read_recording": "read",
    "write_csv": "recording",
}


__getattr__ = lazy_names(__name__, _WHERE)


__all__ = [
    "CSV_HEADER",
    "MODAL_RESULT_KIND",
    "ClippedSignal",
    "DoubleHit",
    "FlatChannel",
    "LowCoherence",
    "ModalError",
    "ModalResult",
    "ModalSettings",
    "Mode",
    "NoHits",
    "NoHoopMode",
    "RecordTooShort",
    "Recording",
    "RecordingFormatError",
    "SimMode",
    "SimSettings",
    "WeakHit",
    "analyze",
    "bat_modes",
    "latest_modal_result",
    "read_csv",
    "read_recording",
    "record_modal_result",
    "simulate",
    "with_measured_hoop",
    "write_csv",
]

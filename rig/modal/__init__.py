"""Modal analysis of impact tests: the bat's hoop and bending frequencies from hammer and accelerometers.

Pure numpy/scipy (pyuff for Universal Files); imports nothing of ours but rig.core.
See docs/modal.md for the formats, the method and the diagnosis rules.
"""

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
from rig.modal.recording import CSV_HEADER, Recording, read_csv, read_recording, write_csv
from rig.modal.simulate import SimMode, SimSettings, bat_modes, simulate

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

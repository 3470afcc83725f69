"""Diagnoses of bad modal recordings: each a typed error whose message names the problem.

A bad recording must give one of these, never a wrong number. `code` is a stable short name for
scripts and JSON; the message says what was found and what to do.
"""

from __future__ import annotations

from rig.core.errors import RigError


class ModalError(RigError):
    """Base of the modal-analysis diagnoses."""

    code = "MODAL_ERROR"


class RecordingFormatError(ModalError, ValueError):
    """The file is not a recording we can read: columns, numbers, NaN, time axis, sampling."""

    code = "FORMAT"


class FlatChannel(ModalError):
    """A channel never changes (sensor dead or not connected)."""

    code = "FLAT_CHANNEL"


class ClippedSignal(ModalError):
    """A channel has flat tops at its extremes: the sensor or the converter saturated."""

    code = "CLIPPED"


class NoHits(ModalError):
    """No hammer pulse rises above the force channel's noise floor."""

    code = "NO_HITS"


class WeakHit(ModalError):
    """A hammer pulse too close to the force channel's noise for a trustworthy FRF."""

    code = "WEAK_HIT"


class DoubleHit(ModalError):
    """A second force pulse within a hit's window (the hammer bounced)."""

    code = "DOUBLE_HIT"


class RecordTooShort(ModalError):
    """The hit windows are too short for the frequency resolution the analysis needs."""

    code = "TOO_SHORT"


class LowCoherence(ModalError):
    """The coherence at the identified hoop mode is too low for its frequency to be trusted."""

    code = "LOW_COHERENCE"


class NoHoopMode(ModalError):
    """No mode where the two accelerometers' FRFs overlay: no hoop frequency to report."""

    code = "NO_HOOP_MODE"


class TooQuiet(ModalError):
    """The taps stand too little above the recording's noise floor."""

    code = "TOO_QUIET"

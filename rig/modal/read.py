"""Reading a recording from a file of any format the modal analysis accepts, chosen by its suffix.

Kept apart from the formats (rig.modal.recording: CSV and the Recording type; rig.modal.uff: Universal
Files), which build on the recording type, so that no format module imports another.
"""

from __future__ import annotations

from pathlib import Path

from rig.modal.recording import Recording, read_csv


def read_recording(path: str | Path) -> Recording:
    """A recording from a .csv file, a Universal File (.uff, .unv: dataset 58 time records) or a
    two-channel .wav file (force, response)."""
    path = Path(path)
    if path.suffix.lower() == ".wav":
        from rig.modal.wav import impact_recording, read_wav

        return impact_recording(read_wav(path))
    if path.suffix.lower() in (".uff", ".unv"):
        from rig.modal.uff import read_uff

        return read_uff(path)
    return read_csv(path)

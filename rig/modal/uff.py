"""Universal File Format (UFF/UNV) recordings through pyuff: dataset 58 time records.

What we expect (docs/modal.md): three dataset-58 records with function type 1 (time response),
even abscissa spacing (or an x array that is evenly spaced) and the same start, step and length:
- the hammer force: ordinate specific data type 4 (force) or 13 (excitation force), in N;
- two accelerations: ordinate specific data type 12, in m/s^2 (a units label 'g' is converted).
Accelerometer 1 is the one whose response direction (|rsp_dir|) is the force's, i.e. in line with
the hammer; if the directions do not decide, the order in the file does (first = accelerometer 1).
Other datasets in the file are ignored.
"""

from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from rig.modal.errors import RecordingFormatError
from rig.modal.recording import Recording, read_recording_bytes

FORCE_TYPES = (4, 13)
ACCEL_TYPE = 12
STANDARD_GRAVITY = 9.80665


def _read_sets(path: Path) -> list[dict[str, Any]]:
    """The file's datasets; read within MAX_BYTES first (pyuff reads a file by name: a device or a
    FIFO is read once, bounded, and its bytes handed over in a temporary file)."""
    import pyuff

    raw = read_recording_bytes(path)
    with contextlib.ExitStack() as stack:
        name = str(path)
        if not path.is_file():
            tmp = stack.enter_context(tempfile.NamedTemporaryFile(suffix=path.suffix))
            tmp.write(raw)
            tmp.flush()
            name = tmp.name
        try:
            sets = pyuff.UFF(name).read_sets()
        except Exception as exc:  # pyuff raises bare Exceptions for malformed files
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise RecordingFormatError(f"{path}: not a readable Universal File ({reason})") from None
    return [sets] if isinstance(sets, dict) else list(sets)


def _values(path: Path, d: dict[str, Any], what: str) -> np.ndarray:
    raw = np.asarray(d.get("data"))
    if np.iscomplexobj(raw):
        raise RecordingFormatError(f"{path}: the {what} record holds complex data, not a time record")
    data = raw.astype(float)
    if str(d.get("ordinate_axis_units_lab", "")).strip().lower() == "g":
        data = data * STANDARD_GRAVITY
    return data


def read_uff(path: str | Path) -> Recording:
    """Force and the two accelerations from the dataset-58 time records of a Universal File."""
    path = Path(path)
    records = [d for d in _read_sets(path) if d.get("type") == 58 and d.get("func_type") == 1]
    if not records:
        raise RecordingFormatError(f"{path}: no dataset 58 time records (function type 1)")
    forces = [d for d in records if d.get("ordinate_spec_data_type") in FORCE_TYPES]
    accels = [d for d in records if d.get("ordinate_spec_data_type") == ACCEL_TYPE]
    if len(forces) != 1 or len(accels) != 2:
        raise RecordingFormatError(
            f"{path}: need one force record (ordinate type 4 or 13) and two acceleration records"
            f" (type 12); found {len(forces)} and {len(accels)}"
        )
    force = forces[0]
    inline = [d for d in accels if abs(int(d.get("rsp_dir", 0))) == abs(int(force.get("rsp_dir", 0)))]
    if len(inline) == 1:
        accels = [inline[0], next(d for d in accels if d is not inline[0])]
    x = np.asarray(force.get("x"), dtype=float)
    for d in accels:
        xd = np.asarray(d.get("x"), dtype=float)
        if xd.shape != x.shape or not np.allclose(xd, x, rtol=0.0, atol=1e-9 * max(1.0, abs(x[-1]))):
            raise RecordingFormatError(
                f"{path}: record {d.get('id1', '?')!r} is sampled differently from the force record"
            )
    return Recording.build(
        x,
        _values(path, force, "force"),
        _values(path, accels[0], "accelerometer 1"),
        _values(path, accels[1], "accelerometer 2"),
        source=str(path),
    )


def write_uff(rec: Recording, path: str | Path) -> Path:
    """Write `rec` as three ASCII dataset-58 time records in the layout read_uff expects.

    Nodes: 1 the hammer (direction +Z), 2 accelerometer 1 (+Z, in line), 3 accelerometer 2 (+X).
    UFF stores the sample step with 6 significant digits: the sample rate read back may differ
    by a few parts per million.
    """
    import pyuff

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    common = {
        "binary": 0,
        "func_type": 1,
        "rsp_ent_name": "bat",
        "ref_ent_name": "bat",
        "ref_node": 1,
        "ref_dir": 3,
        "abscissa_spacing": 1,
        "abscissa_spec_data_type": 17,
        "abscissa_axis_units_lab": "s",
        "orddenom_spec_data_type": 0,
        "z_axis_spec_data_type": 0,
        "x": np.asarray(rec.time_s, dtype=float),
    }
    channels = (
        ("hammer force", 1, 3, 4, "N", rec.force),
        ("accelerometer 1 (in line)", 2, 3, ACCEL_TYPE, "m/s^2", rec.accel1),
        ("accelerometer 2 (90 deg)", 3, 1, ACCEL_TYPE, "m/s^2", rec.accel2),
    )
    sets = [
        pyuff.prepare_58(
            **common,
            id1=name,
            rsp_node=node,
            rsp_dir=direction,
            ordinate_spec_data_type=kind,
            ordinate_axis_units_lab=units,
            data=np.asarray(values, dtype=float),
        )
        for name, node, direction, kind, units, values in channels
    ]
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    return path

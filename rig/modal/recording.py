"""A modal-test recording (hammer force and two accelerations) and its CSV format.

CSV format (docs/modal.md): optional comment lines starting with '#', then the header exactly
`time_s,force_N,accel1_ms2,accel2_ms2` (the time column may be `time_ms` or `time_us` instead),
then one row per sample: time in that unit (strictly increasing, evenly spaced), hammer force in
N, accelerations in m/s^2. Accelerometer 1 sits in line with the hammer, accelerometer 2 at 90
degrees to it around the barrel. A time column slower than an impact test can be (its unit not
the one its name says) is refused, naming the likely unit.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.modal.errors import RecordingFormatError

CSV_COLUMNS = ("time_s", "force_N", "accel1_ms2", "accel2_ms2")
CSV_HEADER = ",".join(CSV_COLUMNS)
CHANNELS = ("force", "accel1", "accel2")
MIN_SAMPLES = 16
UNIFORM_TOLERANCE = 1e-3  # a step may differ from the median step by this fraction (text rounding)
# A time column may name its unit: time_s (the documented one), time_ms or time_us.
TIME_UNITS = {"time_s": 1.0, "time_ms": 1e-3, "time_us": 1e-6}
# Slower than this is no impact test of a bat (its modes lie from about 100 Hz to a few kHz): a time
# column that gives it is most likely written in another unit than its name says.
MIN_SAMPLE_RATE_HZ = 200.0


@dataclass(frozen=True, eq=False)
class Recording:
    """Evenly sampled hammer force (N) and two accelerations (m/s^2); build with `Recording.build`."""

    time_s: np.ndarray
    force: np.ndarray
    accel1: np.ndarray
    accel2: np.ndarray
    source: str = ""

    @classmethod
    def build(
        cls,
        time_s: Iterable[float],
        force: Iterable[float],
        accel1: Iterable[float],
        accel2: Iterable[float],
        source: str = "",
        first_line: int = 1,
    ) -> Recording:
        """Check and freeze the arrays; `first_line` numbers the samples in error messages."""
        arrays = [np.asarray(a, dtype=float).ravel() for a in (time_s, force, accel1, accel2)]
        where = f"{source}: " if source else ""
        n = arrays[0].size
        if any(a.size != n for a in arrays):
            sizes = ", ".join(f"{c} {a.size}" for c, a in zip(CSV_COLUMNS, arrays, strict=True))
            raise RecordingFormatError(f"{where}channels differ in length ({sizes})")
        if n < MIN_SAMPLES:
            raise RecordingFormatError(f"{where}{n} samples; a recording needs at least {MIN_SAMPLES}")
        for name, a in zip(CSV_COLUMNS, arrays, strict=True):
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise RecordingFormatError(
                    f"{where}{name} is {a[bad[0]]} at sample {bad[0] + first_line}"
                    f" ({bad.size} non-finite value(s) in that column)"
                )
        _check_time(arrays[0], where, first_line)
        for a in arrays:
            a.setflags(write=False)
        return cls(*arrays, source=source)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.time_s.size)

    @property
    def dt(self) -> float:
        """Sampling interval, s (mean step, robust to text rounding)."""
        return float((self.time_s[-1] - self.time_s[0]) / (self.n - 1))

    @property
    def fs(self) -> float:
        """Sample rate, Hz."""
        return 1.0 / self.dt

    @property
    def duration_s(self) -> float:
        """Length of the record, s."""
        return self.n * self.dt

    def channel(self, name: str) -> np.ndarray:
        """One of 'force', 'accel1', 'accel2'."""
        return {"force": self.force, "accel1": self.accel1, "accel2": self.accel2}[name]


def _check_time(t: np.ndarray, where: str, first_line: int) -> None:
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        raise RecordingFormatError(
            f"{where}time is not strictly increasing at sample {i + first_line}"
            f" ({t[i - 1]:.9g} s then {t[i]:.9g} s)"
        )
    step = float(np.median(steps))
    off = np.flatnonzero(np.abs(steps - step) > UNIFORM_TOLERANCE * step)
    if off.size:
        i = int(off[0]) + 1
        raise RecordingFormatError(
            f"{where}sampling is not even at sample {i + first_line}: step {steps[i - 1]:.6g} s,"
            f" the rest {step:.6g} s (gaps or a changed sample rate)"
        )


def read_csv(path: str | Path) -> Recording:
    """Read the documented CSV format; every refusal names the file, the line and the problem."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise RecordingFormatError(f"{path}: not a text file") from None
    lines = text.splitlines()
    i = 0
    while i < len(lines) and (not lines[i].strip() or lines[i].lstrip().startswith("#")):
        i += 1
    if i == len(lines):
        raise RecordingFormatError(f"{path}: empty: expected the header {CSV_HEADER!r}")
    header = [c.strip() for c in lines[i].split(",")]
    scale = TIME_UNITS.get(header[0], 1.0) if header else 1.0
    if header and header[0] in TIME_UNITS:
        header = ["time_s", *header[1:]]
    if header != list(CSV_COLUMNS):
        missing = [c for c in CSV_COLUMNS if c not in header]
        extra = [c for c in header if c not in CSV_COLUMNS]
        detail = []
        if missing:
            detail.append(f"missing {', '.join(missing)}")
        if extra:
            detail.append(f"unexpected {', '.join(extra)}")
        if not detail:
            detail.append("columns out of order")
        raise RecordingFormatError(
            f"{path}: line {i + 1}: header {lines[i].strip()!r} must be exactly {CSV_HEADER!r}"
            f" ({'; '.join(detail)})"
        )
    body = [(n + 1, line) for n, line in enumerate(lines[i + 1 :], start=i + 1) if line.strip()]
    if not body:
        raise RecordingFormatError(f"{path}: no samples after the header")
    first_line = body[0][0]
    try:
        data = np.loadtxt([line for _, line in body], delimiter=",", dtype=float, ndmin=2)
    except ValueError:
        _raise_bad_row(path, body)
        raise  # pragma: no cover - _raise_bad_row always raises
    if data.shape[1] != len(CSV_COLUMNS):
        _raise_bad_row(path, body)
    data[:, 0] *= scale
    _check_time_unit(data[:, 0], path, first_line - 1)
    return Recording.build(*data.T, source=str(path), first_line=first_line)


def _check_time_unit(t: np.ndarray, path: Path, header_line: int) -> None:
    """Refuse a time column whose sample rate no impact test has: most likely the wrong unit."""
    if t.size < 2:
        return
    step = float(np.median(np.diff(t)))
    if step > 0 and 1.0 / step < MIN_SAMPLE_RATE_HZ:
        guess = " (in milliseconds, as the steps suggest? name the column time_ms)" if step >= 1e-2 else ""
        raise RecordingFormatError(
            f"{path}: line {header_line}: the time column steps {step:.6g} s, a sample rate of "
            f"{1.0 / step:.4g} Hz, too slow for an impact test (at least {MIN_SAMPLE_RATE_HZ:g} Hz): "
            f"is the time in another unit than its name says{guess}?"
        )


def _raise_bad_row(path: Path, body: list[tuple[int, str]]) -> None:
    for line_no, line in body:
        cells = line.split(",")
        if len(cells) != len(CSV_COLUMNS):
            raise RecordingFormatError(
                f"{path}: line {line_no}: {len(cells)} values, expected {len(CSV_COLUMNS)} ({CSV_HEADER})"
            )
        for name, cell in zip(CSV_COLUMNS, cells, strict=True):
            try:
                float(cell)
            except ValueError:
                raise RecordingFormatError(
                    f"{path}: line {line_no}: {name} {cell.strip()!r} is not a number"
                ) from None
    raise RecordingFormatError(f"{path}: unreadable rows")


def write_csv(rec: Recording, path: str | Path, comments: Iterable[str] = ()) -> Path:
    """Write `rec` in the documented CSV format (comment lines first, each prefixed '# ')."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = np.column_stack([rec.time_s, rec.force, rec.accel1, rec.accel2])
    header = "".join(f"# {c}\n" for c in comments) + CSV_HEADER
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt=["%.10g", "%.8g", "%.8g", "%.8g"])
    return path


def read_recording(path: str | Path) -> Recording:
    """A recording from a .csv file or a Universal File (.uff, .unv: dataset 58 time records)."""
    path = Path(path)
    if not path.is_file():
        raise RecordingFormatError(f"{path}: no such file")
    if path.suffix.lower() in (".uff", ".unv"):
        from rig.modal.uff import read_uff

        return read_uff(path)
    return read_csv(path)

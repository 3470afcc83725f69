"""A modal-test recording (hammer force and two accelerations) and its CSV format.

CSV format (docs/modal.md): optional comment lines starting with '#', then the header exactly
`time_s,force_N,accel1_ms2,accel2_ms2` (the time column may be `time_ms` or `time_us` instead),
then one row per sample: time in that unit (strictly increasing, evenly spaced up to the rounding
of its printed digits or of float32; the rate is a least-squares fit), hammer force in
N, accelerations in m/s^2. Accelerometer 1 sits in line with the hammer, accelerometer 2 at 90
degrees to it around the barrel. A time column slower than an impact test can be (its unit not
the one its name says) is refused, naming the likely unit.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.core.errors import ConfigError, listed, shown
from rig.core.files import read_bounded
from rig.modal.errors import RecordingFormatError

CSV_COLUMNS = ("time_s", "force_N", "accel1_ms2", "accel2_ms2")
CSV_HEADER = ",".join(CSV_COLUMNS)
CHANNELS = ("force", "accel1", "accel2")
MIN_SAMPLES = 16
UNIFORM_TOLERANCE = 1e-3  # a step may differ from the median step by this fraction beyond its rounding
# ... and a time may lie this fraction of a step off the fitted even axis beyond its own rounding (a
# time column summed up in float32 wanders; 0.1 step is a phase error of 0.02 rad at 3 kHz, 51.2 kHz)
EVEN_AXIS_TOLERANCE = 0.1
# A time column may name its unit: time_s (the documented one), time_ms or time_us.
TIME_UNITS = {"time_s": 1.0, "time_ms": 1e-3, "time_us": 1e-6}
# Slower than this is no impact test of a bat (its modes lie from about 100 Hz to a few kHz): a time
# column that gives it is most likely written in another unit than its name says.
MIN_SAMPLE_RATE_HZ = 200.0
# A recording of five hits, four channels at 51.2 kHz, is about 1 MB of CSV; a larger file than
# this is no impact test (and an endless one, /dev/zero or a FIFO, is read no further).
MAX_BYTES = 200_000_000


@dataclass(frozen=True, eq=False)
class Recording:
    """Evenly sampled hammer force (N) and two accelerations (m/s^2); build with `Recording.build`."""

    time_s: np.ndarray
    force: np.ndarray
    accel1: np.ndarray
    accel2: np.ndarray
    source: str = ""
    step_s: float | None = None  # the sampling interval fitted by Recording.build
    responses: int = 2  # 1: one response recorded (a two-channel WAV), copied into both accel columns

    @classmethod
    def build(
        cls,
        time_s: Iterable[float],
        force: Iterable[float],
        accel1: Iterable[float],
        accel2: Iterable[float],
        source: str = "",
        first_line: Lines = 1,
        time_quantum: np.ndarray | float = 0.0,
    ) -> Recording:
        """Check and freeze the arrays; `first_line` numbers the samples in error messages (the
        number of the first, or each sample's own: a file's line numbers).

        `time_quantum` is the last printed digit of each time (s): rounding that the time axis
        may carry without being uneven (a float32 column's spacing is allowed for by itself).
        """
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
                    f"{where}{name} is {a[bad[0]]} at sample {_at(first_line, int(bad[0]))}"
                    f" ({bad.size} non-finite value(s) in that column)"
                )
        step = _check_time(arrays[0], time_quantum, where, first_line)
        for a in arrays:
            a.setflags(write=False)
        t, f, a1, a2 = arrays
        return cls(t, f, a1, a2, source=source, step_s=step)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.time_s.size)

    @property
    def dt(self) -> float:
        """Sampling interval, s: a least-squares line through the times (robust to their rounding)."""
        if self.step_s is not None:
            return self.step_s
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


def time_quantum(cells: Iterable[str]) -> np.ndarray:
    """How finely each printed time was rounded, s: the place value of its last kept digit.

    A cell's own last digit overstates it where an export drops trailing zeros ('%.7g' prints
    1.0000000 as '1'), so each cell is also bounded by the export's digit budget: the most
    significant digits any cell shows, at that cell's magnitude, but never finer than the most
    decimals any cell shows (a fixed-decimals export keeps its zeros and its last digit is right).
    """
    own, digits, magnitude = [], [], []
    for cell in cells:
        text = cell.strip().lower().lstrip("+-")
        exponent = 0
        if "e" in text:
            text, _, exp = text.partition("e")
            exponent = int(exp)
        whole, _, frac = text.partition(".")
        own.append(exponent - len(frac))
        mantissa = (whole + frac).lstrip("0")
        digits.append(len(mantissa))
        # the place of the first significant digit ('12.5' -> 1, '0.0019' -> -3)
        integer = whole.lstrip("0")
        lead = len(integer) - 1 if integer else -1 - (len(frac) - len(frac.lstrip("0")))
        magnitude.append(exponent + lead)
    own_a = np.asarray(own, dtype=float)
    budget = max(digits, default=1)
    finest = float(own_a.min(initial=0.0))
    by_digits = np.maximum(np.asarray(magnitude, dtype=float) - budget + 1, finest)
    return 10.0 ** np.minimum(own_a, by_digits)


def _float32_ulp(t: np.ndarray) -> np.ndarray | float:
    """The float32 spacing at each time if every time is a float32 value (a float32 export), else 0."""
    t32 = t.astype(np.float32)
    if not np.array_equal(t32.astype(float), t):
        return 0.0
    return np.spacing(np.abs(t32)).astype(float)


Lines = int | np.ndarray  # the first sample's number, or every sample's (line numbers in a file)


def _at(lines: Lines, i: int) -> int:
    """Sample i's number in messages: its line in the file where known."""
    return int(lines[i]) if isinstance(lines, np.ndarray) else i + lines


def _check_time(t: np.ndarray, quantum: np.ndarray | float, where: str, first_line: Lines) -> float:
    """Check the time axis and return its step: a least-squares line through the times.

    Each time may carry rounding up to half its `quantum` (the last printed digit), plus half the
    float32 spacing for a float32 column. A step that differs from the first steps' median by more
    than its two times' rounding (plus UNIFORM_TOLERANCE) is a gap (a whole number of steps, the
    rate the same after it), a changed sample rate (the steps after it keep a new length) or an
    uneven step, each named with its sample; then no time may lie further from the fitted line
    than its own rounding allows.
    """
    # the printed digits' rounding, a float32 column's, and a float64 value's own spacing (Unix time)
    q = np.broadcast_to(np.asarray(quantum, dtype=float) + _float32_ulp(t) + np.spacing(np.abs(t)), t.shape)
    n = t.size
    overall = float((t[-1] - t[0]) / (n - 1))
    steps = np.diff(t)
    bad = np.flatnonzero(steps <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        if overall > 0 and steps[i - 1] >= overall - 0.5 * (q[i - 1] + q[i]):
            # rounding to the printed digits alone can give this step: the digits are too few
            raise RecordingFormatError(
                f"{where}the time column is printed to {float(np.median(q)):.3g} s, too coarse for its"
                f" step of {overall:.3g} s: it cannot tell the samples apart (sample {_at(first_line, i)});"
                f" export the time with more digits"
            )
        raise RecordingFormatError(
            f"{where}time is not strictly increasing at sample {_at(first_line, i)}"
            f" ({t[i - 1]:.9g} s then {t[i]:.9g} s)"
        )
    first = min(64, steps.size)
    step = float(np.median(steps[:first]))
    # each step's two roundings, the reference step's own (the median of steps rounded as finely
    # as the first times are: around t = 0 that is finer than later on) and UNIFORM_TOLERANCE
    tol = q[:-1] + q[1:] + 2.0 * float(np.max(q[: first + 1])) + UNIFORM_TOLERANCE * step
    off = np.flatnonzero(np.abs(steps - step) > tol)
    if off.size:
        _raise_uneven(t, steps, int(off[0]), step, tol, where, first_line)
    idx = np.arange(n, dtype=float) - 0.5 * (n - 1)
    fitted = float(np.dot(idx, t - t.mean()) / np.dot(idx, idx))
    residual = np.abs(t - t.mean() - fitted * idx)
    off = np.flatnonzero(residual > 0.5 * q + EVEN_AXIS_TOLERANCE * fitted)
    if off.size:
        i = int(np.argmax(residual))
        raise RecordingFormatError(
            f"{where}sampling is not even: the time column wanders off an even axis (step {fitted:.6g} s)"
            f" by up to {residual[i]:.3g} s ({residual[i] / fitted:.2g} steps, at sample"
            f" {_at(first_line, i)}, {t[i]:.9g} s), more than its printed precision allows"
        )
    return fitted


def _raise_uneven(
    t: np.ndarray, steps: np.ndarray, i: int, step: float, tol: np.ndarray, where: str, first_line: Lines
) -> None:
    """Name what happened at step i (from sample i to i + 1): a gap, a new sample rate, or one odd step."""
    at = f"at sample {_at(first_line, i + 1)}"
    after = steps[i + 1 : i + 17]
    new = float(np.median(after)) if after.size else step
    same_after = abs(new - step) <= float(np.max(tol[i + 1 : i + 17], initial=tol[i]))
    ratio = steps[i] / step
    if same_after and ratio > 1.5 and abs(steps[i] - round(ratio) * step) <= tol[i] * round(ratio):
        raise RecordingFormatError(
            f"{where}a gap {at}: {round(ratio) - 1} samples missing ({t[i]:.9g} s then {t[i + 1]:.9g} s,"
            f" the step is {step:.6g} s)"
        )
    if not same_after and after.size >= 4:
        raise RecordingFormatError(
            f"{where}the sample rate changes {at} from {1 / step:.6g} Hz to {1 / new:.6g} Hz"
            f" (step {step:.6g} s, then {new:.6g} s): export one rate per file"
        )
    raise RecordingFormatError(
        f"{where}sampling is not even {at}: step {steps[i]:.6g} s, the rest {step:.6g} s"
        f" (more than the time's printed precision allows)"
    )


def read_csv(path: str | Path) -> Recording:
    """Read the documented CSV format; every refusal names the file, the line and the problem."""
    path = Path(path)
    raw = read_recording_bytes(path)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise RecordingFormatError(f"{path}: not a text file") from None
    if "\x00" in text:
        raise RecordingFormatError(f"{path}: not a text file: it holds NUL bytes")
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
            detail.append(f"unexpected {listed(extra)}")
        if not detail:
            detail.append("columns out of order")
        for sep, name in ((";", "semicolons"), ("\t", "tabs")):
            if len(header) == 1 and sep in lines[i]:
                detail = [f"the columns are separated by {name}: the separator must be ','"]
        if header and header[-1] == "" and header[:-1] == list(CSV_COLUMNS):
            detail = ["a trailing comma"]
        raise RecordingFormatError(
            f"{path}: line {i + 1}: header {shown(lines[i].strip())} must be exactly {CSV_HEADER!r}"
            f" ({'; '.join(detail)})"
        )
    # blank lines and comment lines inside the data are skipped; messages give each sample's line
    body = [
        (n + 1, line)
        for n, line in enumerate(lines[i + 1 :], start=i + 1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
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
    quantum = scale * time_quantum(line.partition(",")[0] for _, line in body)
    numbers = np.array([n for n, _ in body])
    t, f, a1, a2 = data.T  # the four CSV_COLUMNS (checked above)
    return Recording.build(t, f, a1, a2, source=str(path), first_line=numbers, time_quantum=quantum)


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
                    f"{path}: line {line_no}: {name} {shown(cell.strip())} is not a number"
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


def read_recording_bytes(path: str | Path) -> bytes:
    """A recording file's bytes, at most MAX_BYTES (rig.core.files.read_bounded); a refusal is a
    RecordingFormatError naming the file."""
    try:
        return read_bounded(path, MAX_BYTES, "a recording", binary=True)
    except ConfigError as exc:
        raise RecordingFormatError(str(exc)) from None

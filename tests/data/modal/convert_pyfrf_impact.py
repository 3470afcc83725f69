"""Convert the real impact test of the pyFRF showcase into our modal CSV (tests/data/modal).

Source: https://github.com/ladisk/pyFRF, commit 55431fd3c328ddc719232cc34b891291c9982a2e
("added real measurements to showcase", Janko Slavič, 2016-09-15), files
data/measurements_1.npy ... data/measurements_5.npy. Each file is one triggered record of one
hammer hit: a (3, 25600) float64 array, rows time (s), hammer force and acceleration, 1 s at
25.6 kHz. The source does not state the units; by their size (peaks 69-89 and 440-550) they are
read as N and m/s^2. There is one accelerometer.

Get the files (they were removed from the repository in 2019, so they live in its history):

    git clone https://github.com/ladisk/pyFRF && cd pyFRF
    for k in 1 2 3 4 5; do git show 55431fd:data/measurements_$k.npy > /tmp/measurements_$k.npy; done
    python tests/data/modal/convert_pyfrf_impact.py /tmp tests/data/modal/pyfrf_impact_5hits.csv

What the conversion does, and nothing else:
- keeps the first CUT_SAMPLES samples (0.1 s, the hit 0.8 ms after the start) of each record
  and puts the five records one after the other, in file order; the time column is the sample
  index / 25600 Hz over the whole file. The records were not one continuous recording: at each
  join the signal jumps from the end of one cut record (response still ~10 % of its peak) to the
  quiet start of the next;
- writes the force and the acceleration rounded to 4 decimals (the ADC steps are 2.7e-4 N and
  5.8e-4 m/s^2, so the rounding, at most 5e-5, stays below the data's own precision);
- writes the one accelerometer as both accel1_ms2 and accel2_ms2, since our format has two: the
  file serves to check frequencies, not the hoop/bending classification (both FRFs overlay by
  construction, so every mode reads as "hoop");
- computes reference frequencies from the UNCUT 1 s records (10x the resolution of the cut
  file): H1 = P_fx / P_ff by scipy.signal.csd, rectangular window over each whole record, zero
  padding to 16 x 25600 points, peaks of log10|H1| with a prominence of 0.05 decades and at least
  0.5 % of the largest |H1| between 40 Hz and 7 kHz (where the hammer's spectrum has fallen
  20 dB), each refined by a parabola
  through the three top points; they go into the header as `reference_hz` with their |H1|.
"""

from __future__ import annotations

import argparse
import gzip
from pathlib import Path

import numpy as np
from scipy import signal

FS_HZ = 25600.0
CUT_SAMPLES = 2560
FILES = [f"measurements_{k}.npy" for k in range(1, 6)]
PROMINENCE_DECADES = 0.05  # low: the structure has modes 20-40 Hz apart, resolved at 1 Hz
MIN_SHARE = 0.005  # ... and at least this fraction of the largest |H1|
SOURCE = "https://github.com/ladisk/pyFRF"
COMMIT = "55431fd3c328ddc719232cc34b891291c9982a2e"
BAND_HZ = (40.0, 7000.0)
PAD = 16


def load(folder: Path) -> list[np.ndarray]:
    """The five source records, checked: shape (3, 25600) and a 25.6 kHz time row."""
    records = []
    for name in FILES:
        a = np.load(folder / name)
        if a.shape != (3, 25600):
            raise SystemExit(f"{name}: shape {a.shape}, expected (3, 25600)")
        step = np.diff(a[0])
        if not np.allclose(step, 1.0 / FS_HZ, rtol=1e-6, atol=0.0):
            raise SystemExit(f"{name}: time steps {step.min()}..{step.max()} s, expected 1/{FS_HZ:g}")
        records.append(a)
    return records


def reference_peaks(records: list[np.ndarray]) -> list[tuple[float, float]]:
    """(frequency Hz, |H1|) of the H1 peaks of the uncut records (see the module docstring)."""
    n = records[0].shape[1]
    force = np.concatenate([r[1] for r in records])
    accel = np.concatenate([r[2] for r in records])
    opts = {"fs": FS_HZ, "window": "boxcar", "nperseg": n, "noverlap": 0, "nfft": PAD * n}
    freq, p_ff = signal.csd(force, force, **opts)
    _, p_fx = signal.csd(force, accel, **opts)
    h = np.abs(p_fx / p_ff)
    inside = np.flatnonzero((freq >= BAND_HZ[0]) & (freq <= BAND_HZ[1]))
    level = np.log10(h[inside])
    idx, _ = signal.find_peaks(level, prominence=PROMINENCE_DECADES)
    out = []
    for i in idx:
        if h[inside[i]] < MIN_SHARE * h[inside].max():
            continue  # the noise at anti-resonances, not a mode
        y0, y1, y2 = level[i - 1 : i + 2]
        shift = 0.5 * (y0 - y2) / (y0 - 2.0 * y1 + y2)
        out.append((float(freq[inside[i]] + shift * (freq[1] - freq[0])), float(h[inside[i]])))
    return out


def write(records: list[np.ndarray], out: Path) -> Path:
    """Cut, join and write the CSV with its header comments."""
    force = np.concatenate([r[1, :CUT_SAMPLES] for r in records])
    accel = np.concatenate([r[2, :CUT_SAMPLES] for r in records])
    time = np.arange(force.size) / FS_HZ
    refs = reference_peaks(records)
    comments = [
        "Real impact-hammer test (measured, not simulated): five hits, one accelerometer, 25.6 kHz.",
        f"source: {SOURCE} commit {COMMIT}, data/measurements_1..5.npy",
        "authors: Janko Slavič and the OpenModal project (pyFRF showcase data)",
        "licence: LGPL-3.0 (the repository's licence at that commit; see README.md beside this file)",
        "converted by tests/data/modal/convert_pyfrf_impact.py (read it for every step)",
        "channels: force_N = source row 1 (hammer force, N); accel1_ms2 = accel2_ms2 = source row 2",
        "  (the one accelerometer, m/s^2, written twice: check frequencies with this file, not the",
        "  hoop/bending classification)",
        f"cut: the first {CUT_SAMPLES} samples (0.1 s) of each 1 s record, records 1-5 joined in order;",
        "  the records were not continuous: at each join the signal jumps; values rounded to 4 decimals",
        "reference_hz: H1 peaks of the uncut 1 s records (scipy.signal.csd, rectangular window, zero",
        "  padding x16, prominence 0.05 decades, >= 0.5 % of the largest, 40-7000 Hz)",
        "  as frequency:|H1| in (m/s^2)/N",
        "reference_hz " + " ".join(f"{f:.2f}:{h:.3g}" for f, h in refs),
    ]
    with out.open("w", encoding="utf-8", newline="\n") as fh:
        for line in comments:
            fh.write(f"# {line}\n")
        fh.write("time_s,force_N,accel1_ms2,accel2_ms2\n")
        for t, f, a in zip(time, force, accel, strict=True):
            fa = f"{a:.4f}"
            fh.write(f"{t:.10f},{f:.4f},{fa},{fa}\n")
    return out


def write_response(records: list[np.ndarray], out: Path) -> Path:
    """The uncut records' accelerometer row, joined, as one gzipped CSV column."""
    accel = np.concatenate([r[2] for r in records])
    comments = [
        "Real impact-hammer test (measured, not simulated): the accelerometer of five hits, 25.6 kHz.",
        f"source: {SOURCE} commit {COMMIT}, data/measurements_1..5.npy, row 2 (acceleration)",
        "authors: Janko Slavič and the OpenModal project (pyFRF showcase data)",
        "licence: LGPL-3.0 (the repository's licence at that commit; see README.md beside this file)",
        "converted by tests/data/modal/convert_pyfrf_impact.py --response (read it for every step)",
        f"the five uncut 1 s records joined in file order, {FS_HZ:g} samples per second, m/s^2, 4 decimals",
    ]
    with gzip.open(out, "wt", encoding="utf-8", newline="\n") as fh:
        for line in comments:
            fh.write(f"# {line}\n")
        fh.write("accel_ms2\n")
        fh.writelines(f"{a:.4f}\n" for a in accel)
    return out


def main() -> None:
    """Command line: SOURCE_FOLDER OUT.csv."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="folder holding measurements_1.npy ... measurements_5.npy")
    parser.add_argument("out", type=Path, help="the CSV to write")
    parser.add_argument("--response", type=Path, help="also write the uncut accelerometer row (.csv.gz)")
    args = parser.parse_args()
    records = load(args.folder)
    for path in [write(records, args.out)] + (
        [write_response(records, args.response)] if args.response else []
    ):
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} kB)")


if __name__ == "__main__":
    main()

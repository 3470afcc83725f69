"""`rig modal analyze` on a real impact test, against independent estimates written here with scipy.

The recording (tests/data/modal/README.md): the pyFRF showcase measurement, five hits at 25.6 kHz,
one accelerometer written as both accelerometer columns, each hit's 1 s record cut to its first
0.1 s and the five joined. Two independent references:
- the same file's samples: H1 = P_fx / P_ff by scipy.signal.csd over the five 0.1 s blocks (one
  block per hit), an exponential window falling to 10 % over each block, zero padding x32, peaks
  of log10|H1| with parabolic refinement. At the resolution 1/T = 10 Hz both this peak-pick and
  our fit are pulled by neighbouring modes (the closest pairs here are 21-36 Hz apart) by up to
  a fifth of a bin; we allow a quarter of a bin, 0.25/T = 2.5 Hz, far below the 21 Hz of the
  closest pair, so a match cannot be the wrong mode;
- the header's `reference_hz`: the H1 peaks of the uncut 1 s records (10x the resolution),
  computed by the conversion script from the source files. Its own uncertainty is about
  0.25 Hz: a rectangular and an exponential window on the uncut records agree to that.
No frequencies were published with the data.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import signal

from rig.cli import main
from rig.modal import ModalResult, ModalSettings, analyze, read_recording

DATA = Path(__file__).resolve().parents[1] / "data" / "modal" / "pyfrf_impact_5hits.csv"
HITS = 5
BLOCK = 2560  # samples per hit: each source record cut to its first 0.1 s (README.md)
FS_HZ = 25600.0
BAND_HZ = (40.0, 7000.0)  # where the hammer's spectrum stays within 20 dB of its peak
TOL_HZ = 0.25 * FS_HZ / BLOCK  # a quarter of the resolution 1/T
U_REF_HZ = 0.25  # uncertainty of the uncut records' peaks (rectangular vs exponential window)


def _columns(path: Path) -> dict[str, np.ndarray]:
    """The CSV's columns by header name, read with numpy alone."""
    lines = path.read_text(encoding="utf-8").splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    data = np.loadtxt(lines[head + 1 :], delimiter=",")
    return {name: data[:, j] for j, name in enumerate(lines[head].split(","))}


def _uncut_reference(path: Path) -> list[tuple[float, float]]:
    """(frequency Hz, |H1|) of the uncut records, from the header line `# reference_hz f:h ...`."""
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# reference_hz "):
            pairs = [item.split(":") for item in line.split()[2:]]
            return [(float(f), float(h)) for f, h in pairs]
    raise AssertionError("no reference_hz line")


def _independent_h1_peaks(path: Path) -> list[float]:
    """H1 peaks of the file's five 0.1 s blocks by scipy.signal alone (module docstring)."""
    c = _columns(path)
    assert c["time_s"].size == HITS * BLOCK
    fs = 1.0 / float(np.median(np.diff(c["time_s"])))
    w = signal.windows.exponential(BLOCK, center=0, tau=BLOCK / math.log(10.0), sym=False)
    opts = {"fs": fs, "window": w, "nperseg": BLOCK, "noverlap": 0, "nfft": 32 * BLOCK, "detrend": "constant"}
    freq, p_ff = signal.csd(c["force_N"], c["force_N"], **opts)
    _, p_fx = signal.csd(c["force_N"], c["accel1_ms2"], **opts)
    inside = np.flatnonzero((freq >= BAND_HZ[0]) & (freq <= BAND_HZ[1]))
    level = np.log10(np.abs(p_fx / p_ff)[inside])
    idx, _ = signal.find_peaks(level, prominence=0.5, height=level.max() - 2.0)
    peaks = []
    for i in idx:
        y0, y1, y2 = level[i - 1 : i + 2]
        peaks.append(float(freq[inside[i]] + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) * (freq[1] - freq[0])))
    return peaks


def _nearest(f: float, refs: list[float]) -> float:
    return min(refs, key=lambda r: abs(r - f))


@pytest.fixture(scope="module")
def result() -> ModalResult:
    return analyze(read_recording(DATA))


@pytest.fixture(scope="module")
def independent() -> list[float]:
    return _independent_h1_peaks(DATA)


def test_the_file_is_what_its_readme_says() -> None:
    c = _columns(DATA)
    assert list(c) == ["time_s", "force_N", "accel1_ms2", "accel2_ms2"]
    assert np.allclose(np.diff(c["time_s"]), 1.0 / FS_HZ, rtol=0, atol=1e-12)
    assert np.array_equal(c["accel1_ms2"], c["accel2_ms2"])  # the one accelerometer, twice
    assert DATA.stat().st_size < 600_000
    for k in range(HITS):  # one hammer pulse of 69-89 N per 0.1 s block, 0.8 ms after its start
        block = c["force_N"][k * BLOCK : (k + 1) * BLOCK]
        assert 60 < block.max() < 95 and 15 <= int(np.argmax(block)) <= 30


def _warned(result: ModalResult) -> set[float]:
    """Frequencies named in a 'too close to separate' warning (rounded as printed)."""
    out: set[float] = set()
    for w in result.warnings:
        if "too close to separate" in w or "cannot separate" in w:
            out |= {float(x) for x in re.findall(r"(\d+\.\d) and (\d+\.\d) Hz", w)[0]}
    return out


def test_analyze_is_clean_and_finds_the_independent_peaks(
    result: ModalResult, independent: list[float]
) -> None:
    assert result.n_hits == HITS and result.sample_rate_hz == pytest.approx(FS_HZ, rel=1e-9)
    for k, t in enumerate(result.hit_times_s):  # each hit in its own block
        assert k * BLOCK / FS_HZ < t < k * BLOCK / FS_HZ + 1e-3
    assert result.resolution_hz == pytest.approx(FS_HZ / BLOCK, rel=0.01)
    found = [m.frequency_hz for m in result.modes]
    assert len(independent) == 11  # 810 ... 6078 Hz; the closest pairs are not resolved at 10 Hz
    for r in independent:  # each is found; the extra modes the joint fit separates: next test
        assert abs(r - _nearest(r, found)) <= TOL_HZ, (r, _nearest(r, found))
    for m in result.modes:  # both FRFs are the one accelerometer's: they overlay exactly
        assert m.magnitude_ratio == pytest.approx(1.0, abs=1e-9) and m.kind == "hoop"
        assert m.coherence >= ModalSettings().mode_coherence and m.method == "pole fit"


def test_no_mode_is_made_up(result: ModalResult) -> None:
    """Every mode lies within one resolution bin of a peak of the uncut records (10x the resolution),
    unless a warning says it is too close to its neighbour to separate."""
    ref = [f for f, _ in _uncut_reference(DATA)]
    warned = _warned(result)
    for m in result.modes:
        if round(m.frequency_hz, 1) in warned:
            continue
        assert abs(m.frequency_hz - _nearest(m.frequency_hz, ref)) <= FS_HZ / BLOCK, m.frequency_hz


@pytest.mark.parametrize(
    ("true_hz", "before"),
    [
        (3007.83, "read 3010.2 Hz, U 1.7 Hz"),
        (4127.59, "read 4125.6 Hz, U 1.5 Hz"),
        (4163.49, "not reported (half the largest peak, 36 Hz above 4127.6)"),
        (4392.11, "read 4390.8 Hz, U 0.8 Hz"),
        (4421.48, "not reported"),
    ],
)
def test_close_modes_of_the_real_structure_are_separated(
    result: ModalResult, true_hz: float, before: str
) -> None:
    """Issue 13, finding 4 on real data: the one-pole fit was pulled by neighbours 25-40 Hz away
    (`before`); the joint fit with hidden poles puts each within its U of the uncut records' peak."""
    m = min(result.modes, key=lambda m: abs(m.frequency_hz - true_hz))
    assert abs(m.frequency_hz - true_hz) <= m.expanded_uncertainty_hz + U_REF_HZ, (m.frequency_hz, before)


def test_which_warnings_and_why(result: ModalResult) -> None:
    force = _columns(DATA)["force_N"]
    first = int(np.argmax(force > 0.02 * force.max()))
    assert first < 32  # the record starts 0.8 ms before the first hit: too few quiet samples
    # so the noise comes from the floor of the last window's tail's spectrum (issue 13, finding 6),
    # though the tail still rings at ~11 % of the peak; against the 15 quiet samples the file does
    # have before its first hit (a std of 15 samples is good to about +-20 %):
    accel = _columns(DATA)["accel1_ms2"]
    lead = float(np.std(accel[:15]))
    assert result.noise_source == "tail" and result.accel_noise is not None
    assert 0.67 * lead <= result.accel_noise[0] <= 1.5 * lead
    ringing = [w for w in result.warnings if w.startswith("the bat still rang when hit")]
    close = [w for w in result.warnings if "too close to separate" in w]
    assert len(ringing) == 1 and len(close) == 1 and len(result.warnings) == 2
    assert _warned(result) == {5969.6, 5984.6}  # a pair closer than 2/T = 20 Hz
    # Its cause is the joins: each record starts 0.8 ms before its hit and the window 1 ms before,
    # so it takes a few samples of the previous record's end, still ringing at ~10 % of its peak.
    # Starting the window 0.5 ms before the hit keeps it inside the hit's own record.
    inside = analyze(read_recording(DATA), ModalSettings(pretrigger_s=0.5e-3))
    assert not [w for w in inside.warnings if w.startswith("the bat still rang")]


def test_cli_json_gives_the_same_frequencies(
    result: ModalResult, independent: list[float], capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["modal", "analyze", str(DATA), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["n_hits"] == HITS
    freqs = [m["frequency_hz"] for m in out["modes"]]
    assert freqs == pytest.approx([m.frequency_hz for m in result.modes], abs=1e-9)
    for r in independent:
        assert abs(r - _nearest(r, freqs)) <= TOL_HZ
    assert out["hoop_hz"] == pytest.approx(min(freqs)) and out["warnings"] == list(result.warnings)


@pytest.mark.xfail(
    strict=True,
    reason="left alone (issue 13): at T = 0.1 s two modes of this dense structure are off by more than"
    " their U: 4091.1 Hz (-2.0 Hz, U 1.4; three modes within 40 Hz) and 4965.7 Hz (-4.4 Hz, U 2.5; a"
    " weak mode, 1 % of the largest peak, 61 Hz below a ten times stronger one)",
)
def test_expanded_uncertainty_covers_the_uncut_frequency(result: ModalResult) -> None:
    ref = [f for f, _ in _uncut_reference(DATA)]
    misses = []
    warned = _warned(result)
    for m in result.modes:
        if round(m.frequency_hz, 1) in warned:
            continue  # a warning says these cannot be separated at this record length
        err = abs(m.frequency_hz - _nearest(m.frequency_hz, ref))
        if err > m.expanded_uncertainty_hz + U_REF_HZ:
            misses.append((round(m.frequency_hz, 2), round(err, 2), round(m.expanded_uncertainty_hz, 2)))
    assert not misses


@pytest.mark.xfail(
    strict=True,
    reason="left alone (issue 13): the mode at 3689.5 Hz (a third of the largest peak) lies 20.6 Hz,"
    " about 2/T, above the largest one at 3668.9 Hz and is not separated at T = 0.1 s",
)
def test_every_strong_mode_is_reported(result: ModalResult) -> None:
    ref = _uncut_reference(DATA)
    top = max(h for _, h in ref)
    found = [m.frequency_hz for m in result.modes]
    missed = [f for f, h in ref if h >= 0.1 * top and abs(f - _nearest(f, found)) > TOL_HZ]
    assert not missed

"""`rig modal tap` on a real recording: the pyFRF impact test's accelerometer played as audio.

The data (tests/data/modal/README.md): the five uncut 1 s records of the pyFRF showcase's impact
test, accelerometer row only, joined: five hits 1 s apart, each ringing out (to about 0.3 % of its
peak) before the next, as taps recorded by a microphone would. The WAV is written here with
scipy.io.wavfile (not rig's writer); `rig modal tap` sees no force signal.

References, independent of rig.modal: the H1 peaks of the uncut records that the conversion script
computed with scipy.signal alone (`reference_hz` in pyfrf_impact_5hits.csv, good to about 0.25 Hz:
a rectangular and an exponential window agree to that), and the cut file's own H1 peaks by scipy
(test_real_recording._independent_h1_peaks, good to a quarter of its 10 Hz resolution).

The structure is not a bat (the source does not say what it is): its lowest mode, 810 Hz, lies below
the tap rule's 1000 Hz hoop floor, so the rule calls it bending, and the "hoop" it reports is the
lowest strong, lightly damped mode above 1000 Hz: 3669 Hz, the largest H1 peak of the uncut records
above 1000 Hz and the first there to reach half of it. Both are tested.
"""

from __future__ import annotations

import gzip
import json
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.io import wavfile

from rig.cli import main
from rig.modal.errors import ClippedSignal, RecordTooShort
from rig.modal.output_only import HOOP_MIN_HZ
from rig.modal.tap import TapResult, analyze_tap
from rig.modal.wav import read_wav
from tests.modal.test_real_recording import DATA as IMPACT_CSV
from tests.modal.test_real_recording import U_REF_HZ, _independent_h1_peaks, _uncut_reference
from tests.unit.clirun import run_cli

RESPONSE = IMPACT_CSV.parent / "pyfrf_response_5x1s.csv.gz"
FS_HZ = 25600
HITS = 5
CUT_TOL_HZ = 0.25 * FS_HZ / 2560  # the cut file's H1 peaks: a quarter of its resolution


def _response() -> np.ndarray:
    with gzip.open(RESPONSE, "rt", encoding="utf-8") as fh:
        lines = [line for line in fh if not line.startswith("#")]
    assert lines[0].strip() == "accel_ms2"
    return np.array([float(v) for v in lines[1:]])


def _as_audio(path: Path, x: np.ndarray, level: float = 0.5, pcm16: bool = True) -> Path:
    """x scaled so its peak is `level` of full scale, written by scipy as PCM 16 or float 32."""
    y = x * (level / np.max(np.abs(x)))
    data = np.round(y * 32767).astype(np.int16) if pcm16 else y.astype(np.float32)
    wavfile.write(path, FS_HZ, data)
    return path


@pytest.fixture(scope="module")
def response() -> np.ndarray:
    return _response()


@pytest.fixture(scope="module")
def tapped(tmp_path_factory: pytest.TempPathFactory, response: np.ndarray) -> TapResult:
    return analyze_tap(read_wav(_as_audio(tmp_path_factory.mktemp("tap") / "real.wav", response)))


def test_the_response_is_the_impact_files_accelerometer(response: np.ndarray) -> None:
    """Each hit's first 0.1 s is the cut impact file's accelerometer column, to its 4 decimals."""
    lines = IMPACT_CSV.read_text(encoding="utf-8").splitlines()
    head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
    cut = np.loadtxt(lines[head + 1 :], delimiter=",")[:, 2]
    assert response.size == HITS * FS_HZ
    for k in range(HITS):
        assert np.array_equal(response[k * FS_HZ : k * FS_HZ + 2560], cut[k * 2560 : (k + 1) * 2560])
    tail = [float(np.max(np.abs(response[(k + 1) * FS_HZ - 256 : (k + 1) * FS_HZ]))) for k in range(HITS)]
    assert max(tail) < 0.01 * float(np.max(np.abs(response)))  # each hit has rung out before the next


def test_finds_the_five_taps(tapped: TapResult) -> None:
    assert len(tapped.tap_times_s) == HITS
    # the one warning: a weak (below half the loudest) but lightly damped mode below the hoop picked,
    # which the assumed rule calls bending; the result says so rather than keep quiet
    assert [w.split(" lies")[0] for w in tapped.warnings] == ["a mode at 2640 Hz"]
    for k, t in enumerate(tapped.tap_times_s):
        assert k < t < k + 2e-3  # the hits come 0.8 ms after each record's start
    assert tapped.window_s == pytest.approx(0.5)


def test_lowest_mode_matches_the_independent_references(tapped: TapResult) -> None:
    lowest = min(tapped.modes, key=lambda m: m.frequency_hz)
    uncut = min(f for f, _ in _uncut_reference(IMPACT_CSV))
    cut = min(_independent_h1_peaks(IMPACT_CSV))
    assert uncut == pytest.approx(810.29)
    assert abs(lowest.frequency_hz - uncut) <= 0.01 * uncut
    assert abs(lowest.frequency_hz - uncut) <= lowest.expanded_uncertainty_hz + U_REF_HZ
    assert abs(lowest.frequency_hz - cut) <= CUT_TOL_HZ
    assert lowest.kind == "bending"  # below the rule's hoop floor: no bat has its hoop there


def test_the_rules_hoop_is_the_first_strong_mode_above_the_floor(tapped: TapResult) -> None:
    refs = [(f, h) for f, h in _uncut_reference(IMPACT_CSV) if f >= HOOP_MIN_HZ]
    top = max(h for _, h in refs)
    expected = min(f for f, h in refs if h >= 0.5 * top)
    assert expected == pytest.approx(3668.93)
    hoop = tapped.hoop
    assert abs(hoop.frequency_hz - expected) <= 0.01 * expected
    assert abs(hoop.frequency_hz - expected) <= hoop.expanded_uncertainty_hz + U_REF_HZ


def test_every_reported_mode_is_a_real_one(tapped: TapResult) -> None:
    refs = [f for f, _ in _uncut_reference(IMPACT_CSV)]
    for m in tapped.modes:
        nearest = min(refs, key=lambda r: abs(r - m.frequency_hz))
        assert abs(m.frequency_hz - nearest) <= m.expanded_uncertainty_hz + U_REF_HZ, m.frequency_hz


def test_cli_json_on_float_audio(
    tmp_path: Path, response: np.ndarray, tapped: TapResult, capsys: pytest.CaptureFixture[str]
) -> None:
    wav = _as_audio(tmp_path / "real-f32.wav", response, pcm16=False)
    assert main(["modal", "tap", str(wav), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_taps"] == HITS
    assert out["hoop_hz"] == pytest.approx(tapped.hoop.frequency_hz, abs=0.05)


def test_real_recording_clipped_is_refused(tmp_path: Path, response: np.ndarray) -> None:
    """Played too loud: the sound card clips each tap's first swings at full scale."""
    wav = _as_audio(tmp_path / "loud.wav", np.clip(4.0 * response / np.max(np.abs(response)), -1, 1), 1.0)
    with pytest.raises(ClippedSignal, match="clipped"):
        analyze_tap(read_wav(wav))
    res = run_cli(["modal", "tap", str(wav)])
    assert res.code == 2 and len(res.err.strip().splitlines()) == 1 and "clipped" in res.err


@pytest.mark.parametrize(("seconds", "cause"), [(2.0, "2 tap(s) found"), (0.012, "ms long")])
def test_real_recording_too_short_is_refused(
    tmp_path: Path, response: np.ndarray, seconds: float, cause: str
) -> None:
    wav = _as_audio(tmp_path / "short.wav", response[: int(seconds * FS_HZ)])
    with pytest.raises(RecordTooShort, match=re.escape(cause)):
        analyze_tap(read_wav(wav))
    res = run_cli(["modal", "tap", str(wav)])
    assert res.code == 2 and len(res.err.strip().splitlines()) == 1 and cause in res.err

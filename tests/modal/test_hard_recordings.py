"""Issue 13: recordings that once gave a silent wrong answer or a misleading warning.

Clipping with short stuck runs (finding 3), the band's lower edge (5), the noise test without a
quiet lead-in (6) and the 'still rang' warning on noisy records (8).
"""

from __future__ import annotations

import numpy as np
import pytest

from rig.core.errors import ParameterError
from rig.modal import ClippedSignal, ModalSettings, Recording, SimSettings, analyze, bat_modes, simulate
from rig.modal.hits import check_channels


def _clipped_at(rec: Recording, channel: str, fraction: float) -> Recording:
    """`rec` with one channel saturating at `fraction` of its largest excursion, both signs."""
    chans = {c: rec.channel(c) for c in ("force", "accel1", "accel2")}
    level = fraction * float(np.max(np.abs(chans[channel])))
    chans[channel] = np.clip(chans[channel], -level, level)
    return Recording.build(rec.time_s, chans["force"], chans["accel1"], chans["accel2"], source="clipped")


@pytest.mark.parametrize("channel", ["accel1", "accel2"])
def test_clipping_with_short_stuck_runs_is_found_on_either_accelerometer(channel: str) -> None:
    """At 25.6 kHz a 2800 Hz hoop clipped at 60 % sits at the clip level for 1-2 samples a cycle:
    no run reached 3, and the clipped accelerometer gave made-up modes at 7.7 and 8.5 kHz."""
    rec = simulate(
        SimSettings(fs=25600.0, hits=5, hit_interval_s=0.2, seed=1, modes=bat_modes(2800.0, 175.0))
    )
    clipped = _clipped_at(rec, channel, 0.6)
    stuck = np.isclose(np.abs(clipped.channel(channel)), np.max(np.abs(clipped.channel(channel))), rtol=1e-12)
    runs = np.diff(np.concatenate(([0], stuck.astype(int), [0])))
    assert (
        np.max(np.flatnonzero(runs == -1) - np.flatnonzero(runs == 1)) <= 2
    )  # the short runs of the finding
    with pytest.raises(ClippedSignal, match=rf"{channel} is clipped: \d+ samples in \d+ places stuck at its"):
        analyze(clipped)


@pytest.mark.parametrize("bits", [None, 16, 12])
@pytest.mark.parametrize("hoop", [1400.0, 2800.0])
@pytest.mark.parametrize("fs", [25600.0, 51200.0])
def test_clean_recordings_are_not_called_clipped(bits: int | None, hoop: float, fs: float) -> None:
    """No false alarm: clean records, raw or quantized as an ADC would (the peak at 80 % of full scale)."""
    for seed in range(3):
        rec = simulate(
            SimSettings(fs=fs, hits=4, hit_interval_s=0.15, seed=seed, modes=bat_modes(hoop, 175.0))
        )
        if bits is not None:
            chans = []
            for c in ("force", "accel1", "accel2"):
                x = rec.channel(c)
                lsb = float(np.max(np.abs(x))) / 0.8 / 2 ** (bits - 1)
                chans.append(np.round(x / lsb) * lsb)
            rec = Recording.build(rec.time_s, *chans)
        check_channels(rec)  # raises ClippedSignal on a false alarm


def _low_mode_recording() -> tuple[SimSettings, Recording]:
    s = SimSettings(hits=3, hit_interval_s=1.0, settle=True, seed=4, modes=bat_modes(1800.0, 30.0))
    return s, simulate(s)


def test_the_band_reaches_down_to_what_the_record_length_resolves() -> None:
    """Issue 13, finding 5: a fixed 40 Hz lower edge hid a 30 Hz mode that 1 s windows resolve."""
    _, rec = _low_mode_recording()
    res = analyze(rec)
    assert res.band_hz[0] == pytest.approx(max(3.0 / res.window_s, 10.0))  # 3 bins of 1/T, 10 Hz at least
    first = res.bending_hz[0]
    bending = next(m for m in res.modes if m.kind == "bending")
    assert abs(first - 30.0) <= bending.expanded_uncertainty_hz  # the true first mode, within its U
    assert res.hoop_hz == pytest.approx(1800.0, abs=res.hoop.expanded_uncertainty_hz)  # type: ignore[union-attr]


def test_the_band_is_a_setting() -> None:
    _, rec = _low_mode_recording()
    res = analyze(rec, ModalSettings(f_min_hz=60.0))
    assert res.band_hz[0] == 60.0 and min(res.bending_hz) > 60.0  # the 30 Hz mode is left out, as asked
    high = analyze(rec, ModalSettings(f_min_hz=2000.0, f_max_hz=4000.0))
    assert high.band_hz == (2000.0, 4000.0) and high.hoop is not None
    assert high.hoop_hz == pytest.approx(1.7 * 1800.0, abs=1.0)  # the first hoop *in the band*, as it says
    short = analyze(simulate(SimSettings(hits=3, hit_interval_s=0.1, seed=2)))
    assert short.band_hz[0] == pytest.approx(3.0 / short.window_s)  # a short window cannot resolve low modes
    with pytest.raises(ParameterError, match="f_max_hz"):
        ModalSettings(f_min_hz=500.0, f_max_hz=400.0)


def _true_noise(s: SimSettings) -> tuple[float, float]:
    """The simulator's noise std per accelerometer: `noise` times the noise-free channel's peak."""
    clean = simulate(s.but(noise=0.0))
    return s.noise * float(np.max(np.abs(clean.accel1))), s.noise * float(np.max(np.abs(clean.accel2)))


@pytest.mark.parametrize("noise", [1e-3, 1e-2])
def test_without_a_quiet_lead_in_the_noise_comes_from_the_decayed_tail(noise: float) -> None:
    """Issue 13, finding 6: fewer than 32 samples before the first hit turned the noise test off."""
    s = SimSettings(hits=3, hit_interval_s=0.2, first_hit_s=2e-4, noise=noise, seed=5)  # 10 samples
    res = analyze(simulate(s))
    assert not any("no quiet samples" in w for w in res.warnings)
    assert res.noise_source == "tail"
    for got, true in zip(res.accel_noise, _true_noise(s), strict=True):
        assert got == pytest.approx(true, rel=0.15)  # an estimate of the real noise, not a stand-in
    lead = analyze(simulate(s.but(first_hit_s=0.01)))  # the same test with a quiet lead-in
    assert lead.noise_source == "before the first hit"
    assert [m.kind for m in res.modes] == [m.kind for m in lead.modes]  # the same modes pass the noise test
    for a, b in zip(res.modes, lead.modes, strict=True):
        assert abs(a.frequency_hz - b.frequency_hz) <= a.expanded_uncertainty_hz + b.expanded_uncertainty_hz


@pytest.mark.parametrize("seed", range(4))
def test_tail_noise_sees_the_noise_under_a_ringing_mode(seed: int) -> None:
    """The tail's spectrum floor against a known white noise, under modes 300x louder than it."""
    from rig.modal.hits import tail_noise

    rng = np.random.default_rng(seed)
    fs, n, sigma = 51200.0, 8192, 0.01
    t = np.arange(n) / fs
    ring = sum(3.0 * np.sin(2 * np.pi * f * t + rng.uniform(0, 6)) for f in rng.uniform(100, 5000, 3))
    a1 = ring + sigma * rng.standard_normal(n)
    a2 = 0.5 * ring + 2 * sigma * rng.standard_normal(n)
    rec = Recording.build(t, np.zeros(n) + rng.standard_normal(n), a1, a2)
    got = tail_noise(rec, 0, n)
    assert got is not None
    assert got[0] == pytest.approx(sigma, rel=0.1) and got[1] == pytest.approx(2 * sigma, rel=0.1)


def test_noise_alone_is_not_called_ringing() -> None:
    """Issue 13, finding 8: 'the bat still rang' on a noisy record with 2 s between hits."""
    s = SimSettings(hits=3, hit_interval_s=2.0, settle=True, noise=0.03, seed=6)
    res = analyze(simulate(s))
    assert not any("still rang" in w for w in res.warnings), res.warnings
    # the same noise on a lightly damped hoop (zeta 0.001: 1/e in 88 ms) hit every 60 ms: the bat
    # really still rings, at about half its peak, and the warning stays
    ringing = s.but(
        hit_interval_s=0.06, settle=False, hits=4, modes=bat_modes(1800.0, 175.0, hoop_damping=0.001)
    )
    close = analyze(simulate(ringing), ModalSettings(max_resolution_hz=50))
    assert any("still rang" in w for w in close.warnings), close.warnings


def test_the_accuracy_study_scores_its_hard_cases() -> None:
    """benchmarks/bench_modal.py's hard-case table: a rounded export is answered, a clip diagnosed."""
    from benchmarks.modal_cases import cases, run_case, table

    picked = [c for c in cases() if c.name.startswith(("time rounded", "accelerometer 1 clipped"))]
    results = [run_case(c, 2, 700) for c in picked]
    assert [r.met(2) for r in results] == [True, True]
    assert results[1].diagnoses["CLIPPED"] == 2 and len(results[0].errors) == 2
    rows = table(results, 2)
    assert len(rows) == 4 and rows[3].endswith("| yes |")


def test_one_noisy_hit_makes_up_no_mode() -> None:
    """Review of issue 13: with one hit and 1-2 % noise the hidden-pole search made up a mode a few
    Hz from a bending mode, read it as 'hoop' and reported it as the first hoop (15 of 48 records).
    One hit cannot tell structure from noise: the search is not run, and the result says so."""
    for noise, interval in ((0.02, 1.0), (0.02, 2.0), (0.01, 2.0)):
        for seed in range(6):
            res = analyze(simulate(SimSettings(seed=seed, hits=1, hit_interval_s=interval, noise=noise)))
            assert res.hoop is not None and abs(res.hoop.frequency_hz - 1800.0) < 1.0, (noise, interval, seed)
            assert any("not searched for" in w for w in res.warnings)


@pytest.mark.parametrize(("hz", "hits", "interval"), [(50.0, 1, 0.5), (50.0, 4, 0.2), (60.0, 4, 0.2)])
def test_mains_hum_is_not_a_hoop_mode(hz: float, hits: int, interval: float) -> None:
    """Review of issue 13: hum of 0.1-0.5 % on both accelerometers read as 'first hoop frequency:
    50.0 Hz' (undamped), and --bat stored it. It is left out with a warning naming it."""
    rec = simulate(SimSettings(hits=hits, hit_interval_s=interval, seed=3))
    t = rec.time_s
    hum = 0.003 * float(np.max(np.abs(rec.accel1))) * np.sin(2 * np.pi * hz * t + 0.4)
    noisy = Recording.build(t, rec.force, rec.accel1 + hum, rec.accel2 + hum, source="hum")
    res = analyze(noisy)
    assert res.hoop is not None and abs(res.hoop.frequency_hz - 1800.0) < 1.0
    assert all(abs(m.frequency_hz - hz) > 1.0 for m in res.modes)
    assert any(w.startswith("mains interference left out") for w in res.warnings), res.warnings


def test_a_long_peak_list_is_cut_in_warnings() -> None:
    """Review of issue 13: a 60 s one-hit record listed 10354 buried peaks in one ~60 kB warning."""
    from rig.modal.analysis import LISTED, _listed

    freqs = [100.0 + 3 * k for k in range(500)]
    text = _listed(freqs)
    assert text.count(",") == LISTED - 1 and text.endswith(f"and {500 - LISTED} more up to 1597")
    assert _listed(freqs[:3]) == "100, 103, 106"


def test_a_window_longer_than_the_hit_spacing_is_named_not_blamed_on_the_hammer() -> None:
    """Review of issue 13: --window 5 on hits 0.2 s apart said 'double hit ... the hammer bounced'."""
    from rig.modal import RecordTooShort

    rec = simulate(SimSettings(hits=3, hit_interval_s=0.2, seed=2))
    with pytest.raises(RecordTooShort, match=r"inside the window of 5 s asked for: give a window shorter"):
        analyze(rec, ModalSettings(window_s=5.0))


def test_swapped_accelerometers_and_a_raised_band_are_said() -> None:
    """Review of issue 13: with accelerometer 2 in line with the hammer every bending mode read
    'unclassified' and bending_hz was empty, silently; --band-min 2000 reported the second hoop
    mode as the first without a word."""
    rec = simulate(SimSettings(hits=3, hit_interval_s=0.2, seed=4))
    swapped = Recording.build(rec.time_s, rec.force, rec.accel2, rec.accel1, source="swapped")
    res = analyze(swapped)
    assert res.bending_hz == [] and any("columns swapped?" in w for w in res.warnings), res.warnings
    assert not any("columns swapped?" in w for w in analyze(rec).warnings)
    high = analyze(rec, ModalSettings(f_min_hz=2000.0))
    assert high.hoop_hz == pytest.approx(1.7 * 1800.0, abs=1.0)
    assert any("a hoop mode below it would not be seen" in w for w in high.warnings)

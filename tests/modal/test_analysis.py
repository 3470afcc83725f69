"""Modal analysis of simulated impact tests: recovery within the stated uncertainty, classification,
and a typed diagnosis for every kind of bad recording."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.core.errors import ParameterError
from rig.modal import (
    ClippedSignal,
    DoubleHit,
    FlatChannel,
    LowCoherence,
    ModalResult,
    ModalSettings,
    NoHits,
    Recording,
    RecordTooShort,
    SimMode,
    SimSettings,
    WeakHit,
    analyze,
    bat_modes,
    simulate,
)
from rig.modal.simulate import true_frequencies

from .conftest import BENDING_HZ, HOOP_HZ


@settings(max_examples=12)
@given(
    hoop=st.floats(1400.0, 2800.0),
    damping=st.floats(0.002, 0.02),
    noise=st.floats(0.0, 0.01),
    seed=st.integers(0, 2**16),
)
def test_hoop_frequency_recovered_within_its_uncertainty(
    hoop: float, damping: float, noise: float, seed: int
) -> None:
    s = SimSettings(
        hits=3, hit_interval_s=0.12, noise=noise, seed=seed, modes=bat_modes(hoop, hoop_damping=damping)
    )
    res = analyze(simulate(s))
    assert res.hoop is not None
    assert abs(res.hoop_hz - hoop) <= res.hoop.expanded_uncertainty_hz
    assert res.hoop.expanded_uncertainty_hz < 2.0  # and the uncertainty is useful, not a blanket
    assert res.hoop.damping_ratio == pytest.approx(damping, rel=0.25, abs=3e-4)


def test_classifies_bending_and_hoop_modes(result: ModalResult, settings: SimSettings) -> None:
    assert [m.kind for m in result.modes] == ["bending", "bending", "bending", "hoop", "hoop"]
    np.testing.assert_allclose(result.bending_hz, true_frequencies(settings, "bending"), atol=0.5)
    np.testing.assert_allclose(
        [m.frequency_hz for m in result.modes if m.kind == "hoop"],
        true_frequencies(settings, "hoop"),
        atol=0.5,
    )
    assert result.hoop_hz == pytest.approx(HOOP_HZ, abs=result.hoop.expanded_uncertainty_hz)
    assert result.bending_hz[0] == pytest.approx(BENDING_HZ, abs=0.5)
    for m in result.modes:
        if m.kind == "hoop":
            assert 0.5 <= m.magnitude_ratio <= 2.0 and m.accelerometers == ("accel1", "accel2")
        else:
            assert m.magnitude_ratio >= 4.0 and m.accelerometers == ("accel1",)
        assert m.coherence > (0.99 if m.kind == "hoop" else 0.97)  # bending rings on into the next hit
        assert len(m.per_hit_hz) == result.n_hits == 5
        terms = (m.u_resolution_hz, m.u_fit_hz, m.u_spread_hz, m.u_model_hz)
        assert m.u_hz == pytest.approx(np.sqrt(sum(x**2 for x in terms)))


def test_first_hoop_is_the_lowest_overlaying_mode_not_the_strongest() -> None:
    modes = (
        SimMode(180.0, 0.005, 0.22, 1.0, 0.05, "bending"),
        SimMode(1500.0, 0.01, 0.5, 1.0, -0.9, "hoop"),  # weak: heavy modal mass
        SimMode(2600.0, 0.005, 0.05, 1.0, 0.95, "hoop"),
    )
    res = analyze(simulate(SimSettings(modes=modes, hits=3, hit_interval_s=0.15, seed=9)))
    assert res.hoop_hz == pytest.approx(1500.0, abs=0.5)


def test_accelerometer_90_degrees_off_axis_alone_is_unclassified() -> None:
    modes = (SimMode(400.0, 0.005, 0.2, 0.05, 1.0, "bending"), SimMode(2000.0, 0.005, 0.1, 1.0, -1.0, "hoop"))
    res = analyze(simulate(SimSettings(modes=modes, hits=2, hit_interval_s=0.15)))
    assert [m.kind for m in res.modes] == ["unclassified", "hoop"]
    assert res.modes[0].accelerometers == ("accel2",)


def test_no_hoop_mode_is_reported_not_invented() -> None:
    modes = tuple(m for m in bat_modes(2000.0) if m.kind == "bending")
    res = analyze(simulate(SimSettings(modes=modes, hits=2, hit_interval_s=0.15)))
    assert res.hoop is None and res.hoop_hz is None
    assert len(res.bending_hz) == 3
    assert any("no hoop mode" in w for w in res.warnings)


def test_reversed_force_sensor_gives_the_same_hoop(recording: Recording, result: ModalResult) -> None:
    flipped = Recording.build(recording.time_s, -recording.force, recording.accel1, recording.accel2)
    assert analyze(flipped).hoop_hz == pytest.approx(result.hoop_hz, abs=1e-6)


def test_one_hit_works_and_says_coherence_is_unchecked() -> None:
    res = analyze(simulate(SimSettings(hits=1, hit_interval_s=0.3, modes=bat_modes(HOOP_HZ))))
    assert res.n_hits == 1
    assert res.hoop_hz == pytest.approx(HOOP_HZ, abs=res.hoop.expanded_uncertainty_hz)
    assert res.hoop.u_spread_hz == 0.0 and res.hoop.per_hit_hz == ()
    assert any("one hit" in w for w in res.warnings)


# --- bad recordings: a typed diagnosis, never a number ---------------------------------------


def _fails(s: SimSettings, error: type[Exception], needle: str, modal: ModalSettings | None = None) -> str:
    with pytest.raises(error) as err:
        analyze(simulate(s), modal)
    assert needle in str(err.value)
    return str(err.value)


def test_clipped_force_is_diagnosed() -> None:
    msg = _fails(SimSettings(hits=2, hit_interval_s=0.15, clip_force=0.7), ClippedSignal, "force is clipped")
    assert "consecutive samples stuck at its top value" in msg


def test_clipped_acceleration_is_diagnosed() -> None:
    _fails(SimSettings(hits=2, hit_interval_s=0.15, clip_accel=0.5), ClippedSignal, "accel1 is clipped")


def test_double_hit_is_diagnosed_with_the_hit() -> None:
    msg = _fails(SimSettings(hits=4, hit_interval_s=0.15, double_hit=2), DoubleHit, "hit 3 at 0.3")
    assert "3.00 ms later" in msg or "ms later" in msg
    _fails(SimSettings(hits=1, hit_interval_s=0.3, double_hit=0), DoubleHit, "hit 1")


def test_double_hit_inside_a_given_window() -> None:
    s = SimSettings(hits=2, hit_interval_s=0.3, double_hit=1, double_hit_delay_s=0.08)
    _fails(s, DoubleHit, "hit 2", ModalSettings(window_s=0.2))  # 80 ms: past min_spacing_s, inside 0.2 s


def test_too_short_for_the_resolution() -> None:
    msg = _fails(
        SimSettings(hits=3, hit_interval_s=0.03),
        RecordTooShort,
        "resolution",
        ModalSettings(min_spacing_s=0.01),
    )
    assert "needs <= 20 Hz" in msg


def test_given_window_longer_than_the_record() -> None:
    _fails(
        SimSettings(hits=1, hit_interval_s=0.1),
        RecordTooShort,
        "no hit has a full",
        ModalSettings(window_s=0.5),
    )


def test_window_past_the_end_drops_only_the_last_hit() -> None:
    rec = simulate(SimSettings(hits=3, hit_interval_s=0.3))
    n = round(0.70 * rec.fs)  # the third hit, at 0.61 s, keeps 0.09 s of record
    cut = Recording.build(rec.time_s[:n], rec.force[:n], rec.accel1[:n], rec.accel2[:n])
    res = analyze(cut, ModalSettings(window_s=0.25))
    assert res.n_hits == 2 and any("hit at 0.61" in w and "only" in w for w in res.warnings)
    auto = analyze(cut)  # automatic windows: the short last hit would shorten every window
    assert auto.n_hits == 2 and auto.window_s > 0.29


def test_low_coherence_at_the_hoop_mode_is_diagnosed() -> None:
    """A loose accelerometer 2: its gain changes from hit to hit."""
    rec = simulate(SimSettings(hits=4, hit_interval_s=0.2, seed=5, modes=bat_modes(1800.0)))
    hit = np.clip(((rec.time_s - 0.01) // 0.2).astype(int), 0, 3)
    gain = np.array([1.0, 0.3, 1.2, 0.5])[hit]
    loose = Recording.build(rec.time_s, rec.force, rec.accel1, rec.accel2 * gain, source="loose")
    with pytest.raises(LowCoherence, match=r"coherence 0\.\d+ at the hoop mode 1800\.\d Hz is below 0\.9"):
        analyze(loose)


def test_dead_and_quiet_channels() -> None:
    rec = simulate(SimSettings(hits=2, hit_interval_s=0.15))
    dead = Recording.build(rec.time_s, rec.force, rec.accel1, np.zeros(rec.n))
    with pytest.raises(FlatChannel, match="accel2 is constant"):
        analyze(dead)
    rng = np.random.default_rng(0)
    no_hammer = Recording.build(rec.time_s, rng.normal(0, 0.1, rec.n), rec.accel1, rec.accel2)
    with pytest.raises(NoHits, match="no hammer pulse above"):
        analyze(no_hammer)


def test_weak_hits_in_a_noisy_force_channel() -> None:
    _fails(SimSettings(hits=3, hit_interval_s=0.15, noise=0.08, seed=1), WeakHit, "force channel's noise")


def test_noise_peaks_are_not_modes() -> None:
    res = analyze(simulate(SimSettings(hits=3, hit_interval_s=0.15, noise=0.02, seed=4)))
    assert [m.kind for m in res.modes] == ["bending", "bending", "bending", "hoop", "hoop"]
    assert any("ignored" in w for w in res.warnings)


def test_settings_are_checked() -> None:
    with pytest.raises(ParameterError, match="exp_end"):
        ModalSettings(exp_end=0.0)
    with pytest.raises(ParameterError, match="hoop_ratio"):
        ModalSettings(hoop_ratio=5.0, bending_ratio=4.0)
    with pytest.raises(ParameterError, match="damping_ratio"):
        SimMode(100.0, 1.5, 0.1, 1.0, 1.0, "hoop")

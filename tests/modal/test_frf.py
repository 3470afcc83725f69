"""H1 and coherence against closed forms: a single-degree-of-freedom system struck by the hammer."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal
from scipy.integrate import solve_ivp

from rig.modal import Recording, SimMode, SimSettings, analyze, simulate
from rig.modal.frf import estimate, windows
from rig.modal.hits import Hits, find_pulses, segment
from rig.modal.simulate import pulse_response

MODE = SimMode(1000.0, 0.01, 0.1, 1.0, 0.5, "hoop")
EXP_END = 0.01


def accelerance(s: np.ndarray, mode: SimMode = MODE) -> np.ndarray:
    """H(s) = s^2 / (m (s^2 + 2 zeta wn s + wn^2)): acceleration per unit force of one mode."""
    wn = 2 * math.pi * mode.frequency_hz
    return s**2 / (mode.mass_kg * (s**2 + 2 * mode.damping_ratio * wn * s + wn**2))


@pytest.fixture(scope="module")
def sdof() -> tuple[Recording, Hits]:
    rec = simulate(SimSettings(modes=(MODE,), hits=3, hit_interval_s=0.2, noise=0.0, seed=1))
    hits = segment(
        rec, threshold_sigma=10, threshold_fraction=0.02, pretrigger_s=1e-3, window_s=None, min_spacing_s=0.05
    )
    return rec, hits


def test_simulated_response_matches_numerical_integration() -> None:
    """The closed-form pulse response against solve_ivp of m q'' + c q' + k q = F(t)."""
    t = np.linspace(0.0, 0.01, 2001)
    t0, width, peak = 0.001, 2e-4, 150.0
    force, acc = pulse_response(t, t0, width, peak, MODE)
    wn = 2 * math.pi * MODE.frequency_hz
    m, c, k = MODE.mass_kg, 2 * MODE.damping_ratio * wn * MODE.mass_kg, wn**2 * MODE.mass_kg

    def f_of(tt: float) -> float:
        u = tt - t0
        return peak * math.sin(math.pi * u / width) if 0 <= u <= width else 0.0

    def rhs(tt: float, y: np.ndarray) -> list[float]:
        return [y[1], (f_of(tt) - c * y[1] - k * y[0]) / m]

    sol = solve_ivp(rhs, (0, t[-1]), [0.0, 0.0], t_eval=t, rtol=1e-10, atol=1e-14, max_step=width / 50)
    q_acc = np.array([(f_of(tt) - c * v - k * x) / m for tt, x, v in zip(t, sol.y[0], sol.y[1], strict=True)])
    np.testing.assert_allclose(acc, q_acc, atol=1e-6 * np.max(np.abs(q_acc)))
    np.testing.assert_allclose(force, [f_of(tt) for tt in t], atol=1e-9)


def test_h1_of_an_sdof_system_is_its_accelerance_at_the_shifted_frequency(
    sdof: tuple[Recording, Hits],
) -> None:
    """With the exponential window H1 samples H(j omega + 1/tau) (frf.py); away from low frequencies,
    where the sampled pulse's aliased content matters against a tiny accelerance, it agrees closely."""
    rec, hits = sdof
    frf = estimate(rec, hits, EXP_END)
    exact = accelerance(frf.s)
    band = (frf.freq_hz >= 600) & (frf.freq_hz <= 8000)
    rel = np.abs(frf.h[0, band] - exact[band]) / np.abs(exact[band])
    assert rel.max() < 0.02
    near = (frf.freq_hz >= 900) & (frf.freq_hz <= 1100)
    assert (np.abs(frf.h[0, near] - exact[near]) / np.abs(exact[near])).max() < 0.008
    # without the shift the peak is far off: the window's damping is real and must be accounted for
    unshifted = accelerance(2j * np.pi * frf.freq_hz)
    assert np.max(np.abs(frf.h[0, near] - unshifted[near]) / np.abs(unshifted[near])) > 0.2
    # accelerometer 2 carries half the mode shape
    np.testing.assert_allclose(frf.h[1, band], 0.5 * frf.h[0, band], rtol=1e-9)


def test_coherence_is_one_without_noise(sdof: tuple[Recording, Hits]) -> None:
    rec, hits = sdof
    frf = estimate(rec, hits, EXP_END)
    band = (frf.freq_hz >= 800) & (frf.freq_hz <= 8000)
    assert frf.coherence[:, band].min() > 0.999
    assert frf.n_hits == 3


def test_coherence_drops_with_noise() -> None:
    rec = simulate(SimSettings(modes=(MODE,), hits=4, hit_interval_s=0.2, noise=0.02, seed=2))
    hits = segment(
        rec, threshold_sigma=10, threshold_fraction=0.02, pretrigger_s=1e-3, window_s=None, min_spacing_s=0.05
    )
    frf = estimate(rec, hits, EXP_END)
    k = int(np.argmin(np.abs(frf.freq_hz - 1000.0)))
    assert frf.coherence[0, k] > 0.99  # the resonance stands well above the noise
    high = (frf.freq_hz >= 5000) & (frf.freq_hz <= 8000)
    assert np.median(frf.coherence[0, high]) < 0.99


def test_segment_keeps_the_force_noise_apart_from_the_accelerometers() -> None:
    """noise_n is the force channel's noise floor (find_pulses); the accelerometers' is accel_noise."""
    rec = simulate(SimSettings(modes=(MODE,), hits=4, hit_interval_s=0.2, noise=0.02, seed=2))
    hits = segment(
        rec, threshold_sigma=10, threshold_fraction=0.02, pretrigger_s=1e-3, window_s=None, min_spacing_s=0.05
    )
    _, _, force_noise, _, _ = find_pulses(rec.force, rec.fs, 10, 0.02)
    assert isinstance(hits.noise_n, float) and hits.noise_n == force_noise
    assert hits.accel_noise is not None and len(hits.accel_noise) == 2


def test_spectra_agree_with_scipy_csd(sdof: tuple[Recording, Hits]) -> None:
    """Gxf = conj(F) X as scipy.signal.csd(f, x) defines it, on the same windowed hit."""
    rec, hits = sdof
    one = Hits(
        hits.starts[:1], hits.pulses[:1], hits.window_n, hits.baseline_n, hits.noise_n, hits.threshold_n, 1.0
    )
    forces, resp, _ = windows(rec, one, EXP_END)
    kw = {"fs": rec.fs, "window": "boxcar", "nperseg": one.window_n, "noverlap": 0, "detrend": False}
    _, g_fx = signal.csd(forces[0], resp[0, 0], **kw)
    _, g_ff = signal.welch(forces[0], **kw)
    ours = estimate(rec, one, EXP_END).h[0]
    np.testing.assert_allclose(ours[1:-1], (g_fx / g_ff)[1:-1], rtol=1e-8)


def test_sdof_fit_recovers_frequency_and_damping_exactly(sdof: tuple[Recording, Hits]) -> None:
    rec, _ = sdof
    res = analyze(rec)
    (mode,) = res.modes
    assert mode.frequency_hz == pytest.approx(MODE.frequency_hz, abs=1e-3)
    assert mode.damping_ratio == pytest.approx(MODE.damping_ratio, rel=1e-3)  # window's damping removed
    assert mode.magnitude_ratio == pytest.approx(2.0, rel=1e-6)
    assert mode.kind == "hoop"  # ratio 2 sits on the hoop_ratio bound, inclusive

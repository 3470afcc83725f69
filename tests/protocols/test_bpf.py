"""BPF's formulas against momentum written out here, the two bases kept apart, the correlated u by Monte
Carlo, the procedures' basis and the refusals."""

from __future__ import annotations

import math
import random
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.core.errors import ConfigError
from rig.measure.bpf import bbcor_pivoted, bbcor_unconstrained, bpf, bpf_u, shared_u
from rig.measure.registry import MetricTerms, metric
from rig.protocols.procedure import Procedure

ROOT = Path(__file__).resolve().parents[2]


def _pivoted_by_momentum(v_i: float, v_r: float, m: float, q: float, i_pivot: float) -> float:
    """Angular momentum about the fixed pivot: m v_i Q = -m v_r Q + I w; BBCOR = (v_r + w Q) / v_i."""
    w = m * q * (v_i + v_r) / i_pivot
    return (v_r + w * q) / v_i


def _free_by_momentum(v_i: float, v_r: float, m: float, big_m: float, i_cm: float, b: float) -> float:
    """A free bat: linear momentum gives its centre's speed, angular momentum about the centre its spin;
    the impact point's speed is V + w b; BBCOR = (v_r + V + w b) / v_i."""
    v_cm = m * (v_i + v_r) / big_m
    w = m * b * (v_i + v_r) / i_cm
    return (v_r + v_cm + w * b) / v_i


def test_the_pivoted_basis_is_angular_momentum_about_the_pivot() -> None:
    v_i, v_r, m, q, i_p = 26.82, 4.1, 0.187, 0.53, 0.17
    assert bbcor_pivoted(v_r / v_i, m * q * q / i_p) == pytest.approx(
        _pivoted_by_momentum(v_i, v_r, m, q, i_p), rel=1e-12
    )
    # the registry's BPF is that BBCOR over the ball COR, and its inverse undoes it
    entry = metric("usssa_bpf")
    terms = MetricTerms(k=m * q * q / i_p, v_bat=0.0, v_pitch=0.0, ball_cor=0.47)
    value = entry.value(v_r / v_i, terms)
    assert value == pytest.approx(_pivoted_by_momentum(v_i, v_r, m, q, i_p) / 0.47, rel=1e-12)
    assert entry.e_a_of is not None and entry.e_a_of(value, terms) == pytest.approx(v_r / v_i, rel=1e-12)


def test_the_unconstrained_basis_is_the_free_bats_momentum() -> None:
    v_i, v_r, m, big_m, d, i_p, q = 26.82, 4.1, 0.145, 0.85, 0.4064, 0.19, 0.52
    i_cm = i_p - big_m * d * d
    assert bbcor_unconstrained(v_r / v_i, m, big_m, i_p, d, q) == pytest.approx(
        _free_by_momentum(v_i, v_r, m, big_m, i_cm, q - d), rel=1e-12
    )
    with pytest.raises(ValueError, match="below M d"):
        bbcor_unconstrained(0.2, m, big_m, 0.1, d, q)


@settings(max_examples=200, deadline=None)
@given(
    e_a=st.floats(0.0, 0.4),
    big_m=st.floats(0.5, 1.0),
    d=st.floats(0.25, 0.5),
    excess=st.floats(0.001, 0.1),  # I_cm, kg m^2
    q=st.floats(0.3, 0.75),
)
def test_the_bases_differ_except_at_the_centre_of_percussion(
    e_a: float, big_m: float, d: float, excess: float, q: float
) -> None:
    """A free bat recoils at least as much as a pivoted one (r >= k: the pivot only adds constraint), so
    the unconstrained BBCOR of one e_A is never below the pivoted; equal when Q is the centre of
    percussion about the pivot (d + I_cm / (M d)), where the pivot feels no impulse."""
    m, i_p = 0.145, excess + big_m * d * d
    k = m * q * q / i_p
    free = bbcor_unconstrained(e_a, m, big_m, i_p, d, q)
    assert free >= bbcor_pivoted(e_a, k) - 1e-12
    q_cop = d + excess / (big_m * d)
    assert bbcor_unconstrained(e_a, m, big_m, i_p, d, q_cop) == pytest.approx(
        bbcor_pivoted(e_a, m * q_cop**2 / i_p), rel=1e-9
    )


def test_a_rigid_wall_has_bpf_one_and_a_bad_ball_cor_is_refused() -> None:
    assert bpf(0.47, 0.47) == 1.0
    with pytest.raises(ValueError, match="must be positive"):
        bpf(0.5, 0.0)


def test_the_ball_cors_u_is_correlated_across_hits_by_monte_carlo() -> None:
    """n hits each with its own noise, one ball COR measured once per trial: the spread of mean/COR is
    bpf_u's (the COR's term not divided by sqrt n), and well above the averaged-down figure."""
    rng = random.Random(25)
    true_bbcor, sd_hit, cor, u_cor, n, trials = 0.55, 0.004, 0.47, 0.004, 6, 20000
    values = []
    for _ in range(trials):
        measured_cor = cor + rng.gauss(0.0, u_cor)
        hits = [(true_bbcor + rng.gauss(0.0, sd_hit)) / measured_cor for _ in range(n)]
        values.append(sum(hits) / n)
    mean = sum(values) / trials
    sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (trials - 1))
    stated = bpf_u(true_bbcor / cor, sd_hit / math.sqrt(n), cor, u_cor)
    assert stated.u == pytest.approx(sd, rel=0.03)
    averaged_down = math.hypot(stated.from_bbcor, stated.from_ball_cor / math.sqrt(n))
    assert averaged_down < 0.8 * sd  # what treating the COR's error as independent per hit would claim
    assert stated.from_ball_cor == pytest.approx(true_bbcor / cor * u_cor / cor, rel=1e-12)


@pytest.mark.parametrize(
    ("air_hits", "air_cor", "quadrature"),
    [((1.4, -5.0), (-1.3, 4.4), "under"), ((1.4, -5.0), (1.3, -4.4), "over")],
)
def test_a_sensitivity_shared_by_the_hits_and_the_cor_is_one_term_by_monte_carlo(
    air_hits: tuple[float, float], air_cor: tuple[float, float], quadrature: str
) -> None:
    """The air's sensitivities s (per C, per % RH) drawn once per trial move the hits' BBCOR by
    g s.d_hits and the lot's COR by s.d_cor: the spread of the exact ratio is shared_u's. Combining
    the two sides in quadrature understates it when the offsets differ in sign (the bat's run warm, the
    ball test cool) and overstates it when they agree."""
    rng = random.Random(2611)
    bbcor, cor, g, trials = 0.545, 0.47, 1.02, 40000
    s_t, s_rh = 0.0021, 0.00085  # hypot(0.0015, 0.0015), hypot(0.0006, 0.0006): the assumed defaults
    values = []
    for _ in range(trials):
        a, b = rng.gauss(0.0, s_t), rng.gauss(0.0, s_rh)
        hits = bbcor + g * (a * air_hits[0] + b * air_hits[1])
        values.append(hits / (cor + a * air_cor[0] + b * air_cor[1]))
    mean = sum(values) / trials
    sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (trials - 1))
    stated = shared_u(g, bbcor / cor, cor, air_hits, air_cor, ((s_t**2, 0.0), (0.0, s_rh**2)))
    assert stated == pytest.approx(sd, rel=0.03)
    apart = math.hypot(
        g * math.hypot(s_t * air_hits[0], s_rh * air_hits[1]) / cor,
        bbcor / cor * math.hypot(s_t * air_cor[0], s_rh * air_cor[1]) / cor,
    )
    assert (apart < 0.8 * sd) if quadrature == "under" else (apart > 1.25 * sd)


@pytest.mark.parametrize(
    ("name", "standard", "limit"),
    [("usssa-bpf", "usssa_bpf", 1.15), ("fastpitch-bpf", "fastpitch_bpf", 1.20)],
)
def test_the_bpf_procedures_state_their_limit_speed_and_pivoted_basis(
    name: str, standard: str, limit: float
) -> None:
    p = Procedure.load(name)
    assert p.standard == standard and p.limit == limit and p.basis == "pivoted"
    assert p.target_speed_m_s == pytest.approx(60 * 0.44704, abs=0.005)
    assert p.metric.basis.startswith("pivoted") and "F1890-23" in p.metric.basis and p.metric.needs_ball_cor
    text = (ROOT / "protocols" / f"{name}.toml").read_text(encoding="utf-8")
    assert "pivoted" in text and "F2219-23" in text and "[U]" in text and "[C2]" in text


def test_a_bpf_procedure_claiming_the_unconstrained_basis_is_refused(tmp_path: Path) -> None:
    text = (ROOT / "protocols" / "usssa-bpf.toml").read_text(encoding="utf-8")
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(text.replace('basis = "pivoted"', 'basis = "unconstrained"'), encoding="utf-8")
    with pytest.raises(
        ConfigError, match="basis 'unconstrained': the usssa_bpf metric's basis is the pivoted one"
    ):
        Procedure.load(wrong)
    fast = tmp_path / "fast.toml"
    fast.write_text(text.replace("target_speed_m_s = 26.82", "target_speed_m_s = 60.8"), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"is not the usssa_bpf test speed 26\.82"):
        Procedure.load(fast)

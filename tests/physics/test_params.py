"""Validation: every refused value raises ParameterError naming the parameter; good values pass."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rig.core.errors import ParameterError, RigError
from rig.physics import curve, fast
from rig.physics.bat import PivotedBat
from rig.physics.equations import Impact
from rig.physics.params import DEFAULT_PARAMS, CollisionParams
from rig.physics.reference import solve_reference

NAN, INF = math.nan, math.inf


def assert_names(exc: pytest.ExceptionInfo[ParameterError], name: str) -> None:
    """The error carries the parameter's name, and so does its message."""
    assert exc.value.name == name
    assert str(exc.value).startswith(f"{name} = ")


# --- CollisionParams -----------------------------------------------------------------------------


def test_defaults_are_the_papers_constants() -> None:
    """Founding paper, section 3: m1, m2, k1, c1, c2, a, b."""
    p = DEFAULT_PARAMS
    assert (p.m1, p.m2, p.k1, p.c1, p.c2, p.a, p.b) == (0.145, 0.09, 60e6, 5000.0, 100.0, 0.6495, 0.5202)


def test_k2_and_compression_scale() -> None:
    """k2 = m2 (2 pi f)^2; the length scale stores the inbound KE in the undamped ball spring."""
    p = CollisionParams.build(m2=0.2)
    assert p.k2(1000.0) == pytest.approx(0.2 * (2000.0 * math.pi) ** 2, rel=1e-15)
    d = p.compression_scale(60.8)
    assert p.k1 * d ** (2.0 + p.a) / (2.0 + p.a) == pytest.approx(0.5 * p.m1 * 60.8**2, rel=1e-12)


BAD_FIELDS = [
    ("m1", -0.145),
    ("m1", 0.0),
    ("m2", -1.0),
    ("m2", 0.0),
    ("k1", -1.0),
    ("k1", NAN),
    ("c1", -1.0),
    ("c1", INF),
    ("c2", -0.5),
    ("c2", NAN),
    ("m1", INF),
    ("m2", -INF),
    ("a", -0.01),
    ("a", 1.01),
    ("b", -1e-9),
    ("b", 2.0),
    ("a", NAN),
    ("m2", "heavy"),
]


@pytest.mark.parametrize(("name", "value"), BAD_FIELDS)
def test_collision_params_refuse_bad_values(name: str, value: object) -> None:
    """Negative or zero masses and stiffness, negative damping, exponents outside [0, 1], NaN, inf."""
    with pytest.raises(ParameterError) as exc:
        CollisionParams.build(**{name: value})
    assert_names(exc, name)


def test_collision_params_refuse_unknown_field() -> None:
    """A misspelt field is refused, not ignored."""
    with pytest.raises(ParameterError) as exc:
        CollisionParams.build(c3=1.0)
    assert_names(exc, "c3")


@pytest.mark.parametrize(
    ("name", "value"), [("a", 0.0), ("a", 1.0), ("b", 0.0), ("b", 1.0), ("c1", 0.0), ("c2", 0.0)]
)
def test_collision_params_accept_boundaries(name: str, value: float) -> None:
    """Closed bounds: exponents 0 and 1 and zero damping are valid models."""
    assert getattr(CollisionParams.build(**{name: value}), name) == value


def test_collision_params_are_immutable() -> None:
    """Frozen: a solved Impact cannot have its constants changed under it."""
    with pytest.raises(ValueError):
        DEFAULT_PARAMS.m1 = 1.0  # type: ignore[misc]


def test_parameter_error_is_a_value_error() -> None:
    """Callers may catch ValueError or the project's RigError."""
    assert issubclass(ParameterError, ValueError)
    assert issubclass(ParameterError, RigError)


# --- PivotedBat ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("moi_kgm2", 0.0),
        ("moi_kgm2", -0.2),
        ("moi_kgm2", NAN),
        ("impact_from_pivot_m", 0.0),
        ("impact_from_pivot_m", -0.5),
        ("impact_from_pivot_m", INF),
    ],
)
def test_pivoted_bat_refuses_bad_values(name: str, value: float) -> None:
    """MOI and pivot-to-impact distance must be finite and > 0."""
    values = {"moi_kgm2": 0.2, "impact_from_pivot_m": 0.55, name: value}
    with pytest.raises(ParameterError) as exc:
        PivotedBat.build(**values)
    assert_names(exc, name)


def test_pivoted_bat_refuses_missing_and_unknown_fields() -> None:
    """Both fields are required; extras are refused."""
    with pytest.raises(ParameterError) as exc:
        PivotedBat.build(moi_kgm2=0.2)
    assert exc.value.name == "impact_from_pivot_m"
    with pytest.raises(ParameterError) as exc:
        PivotedBat.build(moi_kgm2=0.2, impact_from_pivot_m=0.55, mass=0.9)
    assert_names(exc, "mass")


# --- Impact --------------------------------------------------------------------------------------


@pytest.mark.parametrize("speed", [0.0, -1.0, NAN, INF, -INF, "fast"])
def test_impact_refuses_bad_speed(speed: object) -> None:
    """Speed must be a finite number > 0."""
    with pytest.raises(ParameterError) as exc:
        Impact(DEFAULT_PARAMS, speed)  # type: ignore[arg-type]
    assert_names(exc, "speed")


@pytest.mark.parametrize("hoop", [0.0, -1250.0, NAN, INF])
def test_impact_refuses_bad_hoop(hoop: float) -> None:
    """Hoop frequency must be finite and > 0 (None, not inf, selects the rigid barrel)."""
    with pytest.raises(ParameterError) as exc:
        Impact(DEFAULT_PARAMS, 60.8, hoop)
    assert_names(exc, "hoop_hz")


@pytest.mark.parametrize("body", [0.0, -0.5, NAN, INF])
def test_impact_refuses_bad_body_mass(body: float) -> None:
    """The free body's effective mass must be finite and > 0."""
    with pytest.raises(ParameterError) as exc:
        Impact(DEFAULT_PARAMS, 60.8, 1250.0, body_mass=body)
    assert_names(exc, "body_mass")


def test_impact_refuses_non_numeric_body_mass() -> None:
    """A non-number is refused like speed and hoop_hz refuse one."""
    with pytest.raises(ParameterError) as exc:
        Impact(DEFAULT_PARAMS, 60.8, 1250.0, body_mass="heavy")  # type: ignore[arg-type]
    assert_names(exc, "body_mass")


def test_impact_normalises_numbers() -> None:
    """Integers and numpy scalars become floats; the rigid barrel has an infinite k2."""
    imp = Impact(DEFAULT_PARAMS, np.float64(60), 1250)
    assert type(imp.speed) is float and type(imp.hoop_hz) is float
    assert Impact(DEFAULT_PARAMS, 60.8).k2 == math.inf


# --- tolerances and methods ----------------------------------------------------------------------

BAD_RTOLS = [0.0, -1e-8, 1e-14, 1e-16, 0.011, 1.0, NAN, INF]


@pytest.mark.parametrize("rtol", BAD_RTOLS)
def test_solvers_refuse_bad_rtol(rtol: float) -> None:
    """rtol must lie in [1e-13, 1e-2] (tighter cannot be honoured in doubles), at every entry point."""
    imp = Impact(DEFAULT_PARAMS, 60.8, 1250.0)
    calls = [
        lambda: fast.solve(imp, rtol),
        lambda: fast.solve_batch([imp], rtol),
        lambda: solve_reference(imp, "DOP853", rtol),
        lambda: curve.cor_grid(DEFAULT_PARAMS, 60.8, np.array([1250.0]), rtol),
        lambda: curve.efficiency_curve(DEFAULT_PARAMS, 60.8, 500.0, 2000.0, 5, rtol=rtol),
    ]
    for call in calls:
        with pytest.raises(ParameterError) as exc:
            call()
        assert_names(exc, "rtol")


@pytest.mark.parametrize("rtol", [1e-13, 1e-2])
def test_solvers_accept_rtol_bounds(rtol: float) -> None:
    """The bounds themselves are valid (and 1e-2 still gives a sane COR)."""
    res = fast.solve(Impact(DEFAULT_PARAMS, 60.8), rtol)
    assert res.cor == pytest.approx(0.4836, abs=0.02)


def test_reference_refuses_unknown_method() -> None:
    """A misspelt method is a refused parameter value, not a failed solve."""
    with pytest.raises(ParameterError) as exc:
        solve_reference(Impact(DEFAULT_PARAMS, 60.8), "Euler")
    assert_names(exc, "method")


# --- curve arguments -----------------------------------------------------------------------------


@pytest.mark.parametrize(("lo", "hi"), [(2000.0, 1000.0), (1000.0, 1000.0)])
def test_curve_refuses_empty_range(lo: float, hi: float) -> None:
    """hoop_max must exceed hoop_min."""
    with pytest.raises(ParameterError) as exc:
        curve.efficiency_curve(DEFAULT_PARAMS, 60.8, lo, hi, 10)
    assert_names(exc, "hoop_max")


@pytest.mark.parametrize("points", [1, 0, -5, 2.5, True])
def test_curve_refuses_bad_points(points: object) -> None:
    """At least two grid points, as a whole number."""
    with pytest.raises(ParameterError) as exc:
        curve.efficiency_curve(DEFAULT_PARAMS, 60.8, 500.0, 2000.0, points)  # type: ignore[arg-type]
    assert_names(exc, "points")


def test_curve_accepts_numpy_integer_points() -> None:
    """A numpy integer is a whole number (e.g. from an array of grid sizes)."""
    res = curve.efficiency_curve(DEFAULT_PARAMS, 60.8, 500.0, 2000.0, np.int64(10))  # type: ignore[arg-type]
    assert res.hoop_hz.size == 10


@pytest.mark.parametrize("speed", [0.0, -60.8, NAN])
def test_curve_refuses_bad_speed(speed: float) -> None:
    """The curve's speed is validated like an Impact's."""
    with pytest.raises(ParameterError) as exc:
        curve.efficiency_curve(DEFAULT_PARAMS, speed, 500.0, 2000.0, 10)
    assert_names(exc, "speed")


@pytest.mark.parametrize("hoops", [[1000.0, -5.0], [1000.0, 0.0], [NAN], [INF, 1000.0]])
def test_cor_grid_refuses_bad_hoops(hoops: list[float]) -> None:
    """Every grid frequency must be finite and > 0."""
    with pytest.raises(ParameterError) as exc:
        curve.cor_grid(DEFAULT_PARAMS, 60.8, np.array(hoops))
    assert exc.value.name == "hoop_hz"


@pytest.mark.parametrize(("name", "lo", "hi"), [("hoop_min", 0.0, 2000.0), ("hoop_max", 500.0, INF)])
def test_curve_names_the_bad_bound(name: str, lo: float, hi: float) -> None:
    """The message names the argument the caller passed."""
    with pytest.raises(ParameterError) as exc:
        curve.efficiency_curve(DEFAULT_PARAMS, 60.8, lo, hi, 10)
    assert_names(exc, name)

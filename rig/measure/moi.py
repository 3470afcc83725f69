"""The bat's MOI about the pivot from the pendulum (ASTM F2398 method), with its uncertainty budget.

The bat swings on the pivot 6 in from the knob; its small-amplitude period T0 gives

    I = m g d T0^2 / (4 pi^2),   T0 = T / (1 + theta0^2 / 16)

with m the bat's mass, d the pivot-to-balance-point distance, g the local gravity, T the timed
period at release amplitude theta0 (first-order amplitude correction). Each input's standard
uncertainty is propagated with its exact sensitivity (GUM, independent inputs); the period's u
combines the timer's resolution over N cycles and the scatter of repeated timings, and, for periods
a host fitted to a swing sensor's samples, the part of the fits' own u the scatter does not show
(so their random error, which the scatter already contains, is counted once).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass

from rig.core.bat import PIVOT_FROM_KNOB_M
from rig.core.config import Pendulum
from rig.core.devices import PendulumPeriod
from rig.core.errors import ParameterError


@dataclass(frozen=True)
class PendulumReading:
    """What the pendulum and the bench give: repeated mean periods over `cycles`, and the set-up."""

    periods_s: tuple[float, ...]  # one mean period per timing (repeat)
    cycles: int
    amplitude_deg: float
    mass_kg: float
    lever_m: float  # pivot to balance point
    gravity_m_s2: float
    # the host's own u of each period when it computed it from sampled angles (a swing sensor): empty
    # when a timer reported the periods
    host_u_s: tuple[float, ...] = ()


@dataclass(frozen=True)
class PendulumUncertainty:
    """Standard uncertainties and resolutions of the pendulum's inputs."""

    timer_resolution_s: float  # of the timed interval of `cycles` periods
    scale_resolution_kg: float
    lever_half_width_m: float  # rectangular: balance point found to +- this
    amplitude_deg: float  # standard u of the release angle
    gravity_m_s2: float  # standard u of local g


def pendulum_uncertainty(config: Pendulum) -> PendulumUncertainty:
    """The pendulum's input uncertainties as the rig config states them."""
    return PendulumUncertainty(
        timer_resolution_s=config.timer_resolution_s,
        scale_resolution_kg=config.scale_resolution_kg,
        lever_half_width_m=config.balance_point_u_m,
        amplitude_deg=config.amplitude_u_deg,
        gravity_m_s2=config.gravity_u_m_s2,
    )


@dataclass(frozen=True)
class MoiInput:
    """One row of the MOI's budget."""

    name: str
    what: str
    value: float
    unit: str
    u: float  # standard uncertainty of the input, in its unit
    sensitivity: float  # dI/d(input), kg m^2 per unit
    share: float = 0.0  # of u(I)^2

    @property
    def u_moi(self) -> float:
        """|sensitivity| u: this input's part of u(I), kg m^2."""
        return abs(self.sensitivity) * self.u


@dataclass(frozen=True)
class MoiBudget:
    """The MOI, its standard uncertainty and every input's contribution."""

    moi_kgm2: float
    u_kgm2: float
    source: str
    inputs: tuple[MoiInput, ...]

    @property
    def relative_u(self) -> float:
        """u(I) / I."""
        return self.u_kgm2 / self.moi_kgm2

    def as_dict(self) -> dict[str, object]:
        """Plain values for the record: the MOI, u and the contributions table."""
        return {
            "moi_kgm2": self.moi_kgm2,
            "u_kgm2": self.u_kgm2,
            "relative_u": self.relative_u,
            "source": self.source,
            "contributions": [
                {
                    "input": i.name,
                    "what": i.what,
                    "value": i.value,
                    "unit": i.unit,
                    "u": i.u,
                    "sensitivity": i.sensitivity,
                    "u_moi_kgm2": i.u_moi,
                    "share": i.share,
                }
                for i in self.inputs
            ],
        }


def moi_from_period(
    mass_kg: float, gravity: float, lever_m: float, period_s: float, amplitude_rad: float
) -> float:
    """I = m g d T0^2 / (4 pi^2) with T0 = T / (1 + theta0^2/16)."""
    t0 = period_s / (1.0 + amplitude_rad**2 / 16.0)
    return mass_kg * gravity * lever_m * t0 * t0 / (4.0 * math.pi**2)


def period_u(periods_s: Sequence[float], cycles: int, timer_resolution_s: float) -> tuple[float, float]:
    """(resolution part, scatter part) of u of the mean period.

    The timer reads an interval of `cycles` periods between two quantized instants: triangular,
    u = res / sqrt(6), per period / cycles, per mean of r timings / sqrt(r). The scatter of the r
    timings is Type A: s / sqrt(r) (0 with one timing).
    """
    r = len(periods_s)
    res = timer_resolution_s / math.sqrt(6.0) / cycles / math.sqrt(r)
    scatter = statistics.stdev(periods_s) / math.sqrt(r) if r >= 2 else 0.0
    return res, scatter


def pendulum_budget(reading: PendulumReading, unc: PendulumUncertainty) -> MoiBudget:
    """The MOI from the pendulum and its GUM budget (exact partial derivatives).

    With the host fit's u of each period (`host_u_s`, a swing sensor), u_host of their mean is
    sqrt(sum u_i^2) / r. The scatter of the r timings (T_scatter, s / sqrt(r)) is an estimate of
    the same random error, so adding u_host in full would count it twice. The `T_host` row holds
    only what u_host goes beyond the scatter, sqrt(max(0, u_host^2 - u_scatter^2)): T_scatter and
    T_host combine to max(u_scatter, u_host). One timing (scatter 0) keeps the whole host u.
    """
    r = reading
    if not r.periods_s or r.cycles < 1:
        raise ParameterError("periods_s", r.periods_s, "need at least one timing of at least one cycle")
    values = (*r.periods_s, r.mass_kg, r.lever_m, r.gravity_m_s2)
    if not all(math.isfinite(v) and v > 0.0 for v in values) or not 0.0 <= r.amplitude_deg < 45.0:
        raise ParameterError("pendulum", values, "periods, mass, lever and g must be > 0, amplitude 0-45 deg")
    t = statistics.fmean(r.periods_s)
    theta = math.radians(r.amplitude_deg)
    moi = moi_from_period(r.mass_kg, r.gravity_m_s2, r.lever_m, t, theta)
    u_res, u_scatter = period_u(r.periods_s, r.cycles, unc.timer_resolution_s)
    d_theta = -moi * 2.0 * (theta / 8.0) / (1.0 + theta**2 / 16.0)  # dI/dtheta0, per rad
    rows = [
        MoiInput("T_res", f"period: timer resolution over {r.cycles} cycles", t, "s", u_res, 2 * moi / t),
        MoiInput(
            "T_scatter", f"period: scatter of {len(r.periods_s)} timings", t, "s", u_scatter, 2 * moi / t
        ),
        MoiInput(
            "m_bat",
            "bat mass (scale resolution)",
            r.mass_kg,
            "kg",
            unc.scale_resolution_kg / math.sqrt(12.0),
            moi / r.mass_kg,
        ),
        MoiInput(
            "d",
            "pivot to balance point",
            r.lever_m,
            "m",
            unc.lever_half_width_m / math.sqrt(3.0),
            moi / r.lever_m,
        ),
        MoiInput(
            "theta0",
            "release amplitude (amplitude correction)",
            r.amplitude_deg,
            "deg",
            unc.amplitude_deg,
            d_theta * math.pi / 180.0,
        ),
        MoiInput("g", "local gravity", r.gravity_m_s2, "m/s²", unc.gravity_m_s2, moi / r.gravity_m_s2),
    ]
    if r.host_u_s:  # independent fits, one per timing: u of their mean, less what the scatter shows
        u_host = math.sqrt(sum(u * u for u in r.host_u_s)) / len(r.host_u_s)
        beyond = math.sqrt(max(0.0, u_host * u_host - u_scatter * u_scatter))
        what = (
            f"period: host fit's u of the mean of {len(r.host_u_s)} timings, beyond their scatter "
            "(with T_scatter: the larger of the two)"
        )
        rows.insert(2, MoiInput("T_host", what, t, "s", beyond, 2 * moi / t))
    return _finish(moi, "pendulum", rows)


def pendulum_moi(
    timings: Sequence[PendulumPeriod], mass_kg: float, balance_point_m: float, pendulum: Pendulum
) -> tuple[PendulumReading, MoiBudget]:
    """The MOI about the pivot from repeated swing timings, and its budget (the inverse of the
    simulator's pendulum period). `balance_point_m` is measured from the knob; the lever is the
    distance from the pivot to it; the amplitude is the timings' mean."""
    if not timings:
        raise ParameterError("timings", timings, "need at least one pendulum timing")
    lever = balance_point_m - PIVOT_FROM_KNOB_M
    if not lever > 0.0:
        raise ParameterError("balance_point_m", balance_point_m, "the balance point must lie past the pivot")
    reading = PendulumReading(
        periods_s=tuple(t.period_s for t in timings),
        cycles=timings[0].cycles,
        amplitude_deg=sum(t.amplitude_deg for t in timings) / len(timings),
        mass_kg=mass_kg,
        lever_m=lever,
        gravity_m_s2=pendulum.gravity_m_s2,
        host_u_s=tuple(t.u_s for t in timings if t.u_s is not None),
    )
    return reading, pendulum_budget(reading, pendulum_uncertainty(pendulum))


def entered_budget(moi_kgm2: float, u_kgm2: float) -> MoiBudget:
    """An MOI entered from elsewhere, with the standard uncertainty it states."""
    if not (math.isfinite(moi_kgm2) and moi_kgm2 > 0.0 and math.isfinite(u_kgm2) and u_kgm2 > 0.0):
        raise ParameterError("moi", (moi_kgm2, u_kgm2), "an entered MOI and its u must be finite and > 0")
    return _finish(
        moi_kgm2,
        "entered",
        [MoiInput("I_entered", "entered MOI (its stated u)", moi_kgm2, "kg m²", u_kgm2, 1.0)],
    )


def _finish(moi: float, source: str, rows: list[MoiInput]) -> MoiBudget:
    var = sum(i.u_moi**2 for i in rows)
    shared = [MoiInput(**{**i.__dict__, "share": (i.u_moi**2 / var if var > 0 else 0.0)}) for i in rows]
    return MoiBudget(moi, math.sqrt(var), source, tuple(shared))

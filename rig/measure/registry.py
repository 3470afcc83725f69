"""The metric registry: every quantity a shot gives and every performance metric, declared once.

A metric (Metric) has its formula from e_A and the shot's terms (MetricTerms: k, V_bat, V_pitch,
which rig.measure.metrics derives from v_in, v_out, Q, I, m_ball, the bat's length and the swing
model), its inverse where one exists, a label and unit, the range a procedure's limit must lie in,
the measurement model's output its uncertainty budget propagates (and the factor carrying that u to
the metric), and whether the calibrated model cross-check supports it. Procedures name a metric by
its name; everything else reads this registry. `register` adds one (docs/procedures.md, "Adding a
metric"); `registered` adds one for the length of a `with` block.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import date
from types import MappingProxyType

from rig.core.errors import ConfigError
from rig.core.units import MPH
from rig.measure import bpf as bpf_table
from rig.measure import softball


@dataclass(frozen=True)
class MetricTerms:
    """What a metric depends on besides e_A: k = m Q^2 / I, the bat's and the pitch's speed (m/s),
    and the run's ball COR on the rigid wall (None: the run has none; a BPF needs it)."""

    k: float
    v_bat: float
    v_pitch: float
    ball_cor: float | None = None


@dataclass(frozen=True)
class Quantity:
    """A named quantity of a shot (e_A, k, V_bat, ...): how it is written and where it comes from."""

    name: str
    label: str
    unit: str
    definition: str


@dataclass(frozen=True)
class Metric(Quantity):
    """A performance metric a procedure can certify (see the module's docstring for each field)."""

    value: Callable[[float, MetricTerms], float]  # the metric from e_A
    limit_range: tuple[float, float]  # a procedure's limit lies in (low, high]
    budget_output: str  # the output of rig.measure.model whose u it takes
    title: str = ""  # how a chooser names its built-in procedure ("" : the label)
    e_a_of: Callable[[float, MetricTerms], float] | None = None  # the inverse, where one exists
    u_scale: Callable[[MetricTerms], float] | None = None  # d(metric)/d(budget output); None: 1
    u_scale_text: str = ""  # u_scale in words, for the certificate
    # rig model calibrate and the calibrated cross-check support it (needs a metric affine in e_A and
    # a population column, rig.population.dataset: its own, else the runs' BBCOR is fitted and the
    # metric predicted through e_A, rig.population.calibrate.fitted_quantity); the uncalibrated
    # prediction needs neither
    cross_check: bool = False
    needs_length: bool = False  # depends on the bat's length (the swing model)
    test_speed_m_s: float | None = None  # the speed its standard fires at; a procedure must match it
    basis: str = ""  # the constraint its e_A or BBCOR assumes (rig.measure.bpf: PIVOTED or UNCONSTRAINED)
    # divided by the run's ball COR (BPF): computed only where the run has one (MetricTerms.ball_cor),
    # whose u enters the mean once, correlated across the hits (rig.measure.bpf.bpf_u)
    needs_ball_cor: bool = False

    def scale(self, terms: MetricTerms) -> float:
        """The factor from the budget output's u to the metric's u (1 when it is the metric)."""
        return 1.0 if self.u_scale is None else self.u_scale(terms)


# the basis of a metric from e_A alone (BESR, BBS): the e_A of the pivoted bat, as BBCOR's
PIVOTED_E_A = "pivoted: e_A = v_out / v_in of the stationary bat on the rig's pivot (WSU SSL glossary)"


def bbcor(e_a: float, k: float) -> float:
    """BBCOR = e_A (1 + k) + k (founding paper, Eq. 5)."""
    return e_a * (1.0 + k) + k


def ea_from_bbcor(bbcor_value: float, k: float) -> float:
    """Inverse of Eq. 5: e_A = (BBCOR - k) / (1 + k)."""
    return (bbcor_value - k) / (1.0 + k)


def besr(e_a: float) -> float:
    """BESR = e_A + 1/2, e_A of the pivoted bat (WSU SSL glossary; the cannon method of ASTM F2219)."""
    return e_a + 0.5


def bbs(e_a: float, v_pitch: float, v_bat: float) -> float:
    """BBS = V_pitch e_A + V_bat (e_A + 1) (founding paper, Eq. 4)."""
    return v_pitch * e_a + v_bat * (e_a + 1.0)


def _ball_cor(t: MetricTerms) -> float:
    if t.ball_cor is None:
        raise ConfigError("a BPF needs the run's ball COR (rig certify --ball-lot LOT)")
    return t.ball_cor


def _bpf(std: bpf_table.BpfStandard) -> Metric:
    """One body's BPF (rig.measure.bpf): the pivoted BBCOR over the run's ball COR."""
    return Metric(
        std.name,
        f"BPF ({std.body})",
        "",
        "BPF = BBCOR / ball COR (WSU SSL glossary; ASTM F1890), BBCOR on the pivoted basis of F1890-23: "
        "e_A (1 + k) + k, k = m Q^2 / I_pivot; ball COR: the lot's against a rigid flat wall at 60 mph "
        "(ASTM F1887, rig balls test --procedure ball-cor)",
        value=lambda e_a, t: bbcor(e_a, t.k) / _ball_cor(t),
        e_a_of=lambda v, t: ea_from_bbcor(v * _ball_cor(t), t.k),
        limit_range=(0.0, 3.0),  # a ratio of CORs: a rigid wall is 1.00, a bat above it by a few tenths
        budget_output="bbcor",
        u_scale=lambda t: 1.0 / _ball_cor(t),
        u_scale_text="dBPF/dBBCOR = 1 / ball COR (the ball COR's own u added once, correlated)",
        title=f"{std.body} BPF {std.limit:g}",
        test_speed_m_s=bpf_table.BPF_SPEED_M_S,
        basis=f"{bpf_table.PIVOTED} ({bpf_table.F1890})",
        needs_ball_cor=True,
        # calibrated on the runs' BBCOR at 60 mph; predicted as calibrated BBCOR / the run's ball COR
        cross_check=True,
    )


def _softball_bbs(ed: softball.SoftballEdition) -> Metric:
    """One USA Softball edition's BBS (rig.measure.softball): BBS with its constants, from e_A."""
    return Metric(
        ed.metric_name,
        f"BBS (USA Softball {ed.key})",
        "m/s",
        f"BBS = V_pitch e_A + V_bat (e_A + 1), USA Softball edition of {ed.effective.isoformat()}: "
        f"{ed.note}; V_bat = V_bat(BESR swing) x {ed.bat_speed_m_s / MPH:g} / 66 "
        "(the same swing geometry [U]; founding paper, Eq. 4)",
        value=lambda e_a, t: ed.bbs(e_a, t.v_bat),
        e_a_of=lambda v, t: (v - ed.bat_speed(t.v_bat)) / (ed.pitch_speed_m_s + ed.bat_speed(t.v_bat)),
        limit_range=(0.0, 100.0),  # a ball speed, as BBS
        budget_output="e_a",
        u_scale=lambda t: ed.pitch_speed_m_s + ed.bat_speed(t.v_bat),
        u_scale_text="dBBS/de_A = V_pitch + V_bat (USA Softball constants)",
        title=f"USA Softball BBS ({ed.key})",
        needs_length=True,
        test_speed_m_s=ed.cannon_speed_m_s,
        basis=PIVOTED_E_A,
        cross_check=True,  # calibrated on the runs' BBCOR at the cannon speed; predicted from its e_A
    )


_QUANTITIES: dict[str, Quantity] = {
    q.name: q
    for q in (
        Quantity(
            "e_a", "e_A", "", "e_A = v_out / v_in, stationary bat (collision efficiency; WSU SSL glossary)"
        ),
        Quantity(
            "k",
            "k",
            "",
            "k = m_ball Q^2 / I, Q pivot-to-impact, I MOI about the pivot (founding paper, Eq. 5)",
        ),
        Metric(
            "bbcor",
            "BBCOR",
            "",
            "BBCOR = e_A (1 + k) + k (founding paper, Eq. 5; WSU SSL glossary, stationary bat)",
            value=lambda e_a, t: bbcor(e_a, t.k),
            e_a_of=lambda v, t: ea_from_bbcor(v, t.k),
            # a COR: (0, 1]
            limit_range=(0.0, 1.0),
            budget_output="bbcor",
            title="NCAA BBCOR",
            cross_check=True,
            # the stationary bat on the rig's pivot (WSU SSL glossary; standards.md's BBCOR formula [I])
            basis=f"{bpf_table.PIVOTED} (the stationary bat on the rig's pivot, WSU SSL glossary)",
        ),
        Metric(
            "besr",
            "BESR",
            "",
            "BESR = e_A + 1/2, e_A of the stationary bat on the rig's pivot (WSU SSL glossary; the cannon "
            "test method of ASTM F2219; Falcon BESR sheet, rearranged)",
            value=lambda e_a, t: besr(e_a),
            e_a_of=lambda v, t: v - 0.5,
            limit_range=(0.5, 1.5),  # e_A + 1/2 with e_A in (0, 1]
            budget_output="besr",
            title="NCAA BESR",
            cross_check=True,
            basis=PIVOTED_E_A,
        ),
        Quantity(
            "besr_eq3",
            "BESR (Eq. 3)",
            "",
            "BESR_Eq3 = (v_out - dv)/(v_in - dv) + 1/2, dv = 60.8 m/s - V_contact (founding paper, "
            "Eq. 3, as printed); equals e_A + 1/2 only when dv = 0, i.e. V_contact = 60.8 m/s",
        ),
        Metric(
            "bbs",
            "BBS",
            "m/s",
            "BBS = V_pitch e_A + V_bat (e_A + 1) (founding paper, Eq. 4; Nathan AJP 2003), "
            "V_bat from the SwingModel (original BESR kinematics, Nathan BRJ 2003)",
            value=lambda e_a, t: bbs(e_a, t.v_pitch, t.v_bat),
            e_a_of=lambda v, t: (v - t.v_bat) / (t.v_pitch + t.v_bat),
            # a ball speed: (0, 100] m/s (100 m/s is 224 mph, beyond any batted ball)
            limit_range=(0.0, 100.0),
            # BBS is linear in e_A and dominated by it; the swing model is a definition
            budget_output="e_a",
            u_scale=lambda t: t.v_pitch + t.v_bat,
            u_scale_text="dBBS/de_A = V_pitch + V_bat",
            title="BBS (batted-ball speed)",
            cross_check=True,
            needs_length=True,
            basis=PIVOTED_E_A,
        ),
        *(_softball_bbs(e) for e in softball.EDITIONS),
        *(_bpf(s) for s in bpf_table.STANDARDS),
        Quantity(
            "ball_cor",
            "ball COR",
            "",
            "ball COR = v_rebound / v_inbound of the ball against a rigid flat wall at 60 mph, the run's "
            "value being the lot's latest ball-cor result "
            "(ASTM F1887; rig balls test --procedure ball-cor)",
        ),
        Quantity(
            "v_bat",
            "V_bat",
            "m/s",
            "V_bat(Q) = V_ref r(Q) / r_ref: rigid rotation about the swing pivot (SwingModel)",
        ),
    )
}
BUILTIN_METRICS = tuple(n for n, q in _QUANTITIES.items() if isinstance(q, Metric))
# the built-in procedure files, protocols/<name>.toml, as a chooser names them (title, name); the
# USA Softball one names the family whose edition its date chooses (rig.measure.softball)
BUILTIN_PROCEDURES: tuple[tuple[str, str], ...] = (
    *(
        (m.title or m.label, m.name)
        for m in _QUANTITIES.values()
        if m.name in ("bbcor", "besr", "bbs") and isinstance(m, Metric)
    ),
    ("USA Softball BBS", "softball-bbs"),
    *((f"{s.body} BPF {s.limit:g}", s.name.replace("_", "-")) for s in bpf_table.STANDARDS),
)
_DEFINITIONS: dict[str, str] = {}
DEFINITIONS: MappingProxyType[str, str] = MappingProxyType(_DEFINITIONS)  # a live view of every formula


def _refresh() -> None:
    _DEFINITIONS.clear()
    _DEFINITIONS.update({n: q.definition for n, q in _QUANTITIES.items()})


_refresh()


def resolve(name: str, on: date | None) -> str:
    """A procedure's `standard`: a metric's name, or a dated family's (usas_bbs) resolved to the
    edition in force on `on` (ConfigError without a date or before the first edition)."""
    if name != softball.FAMILY:
        return name
    if on is None:
        raise ConfigError(f"{name!r} needs the procedure's edition_date to choose its edition")
    return softball.edition_on(on).metric_name


def metrics() -> tuple[Metric, ...]:
    """Every registered metric, the built-in ones first."""
    return tuple(q for q in _QUANTITIES.values() if isinstance(q, Metric))


def metric_names() -> tuple[str, ...]:
    """The names a procedure may give as its `standard`."""
    return tuple(m.name for m in metrics())


def cross_checked() -> tuple[str, ...]:
    """The metrics the calibrated model cross-check (rig model calibrate) supports."""
    return tuple(m.name for m in metrics() if m.cross_check)


def find(name: str | None) -> Metric | None:
    """The metric of this name, or None."""
    q = _QUANTITIES.get(name or "")
    return q if isinstance(q, Metric) else None


def metric(name: str) -> Metric:
    """The metric of this name; ConfigError in one line naming the known ones."""
    found = find(name)
    if found is None:
        raise ConfigError(f"unknown metric {name!r}; known: {', '.join(metric_names())}")
    return found


def label(name: str | None) -> str:
    """How a metric or quantity is named in text and tables (an unknown name: upper case)."""
    q = _QUANTITIES.get(name or "")
    return q.label if q is not None else (name or "metric").upper()


def unit(name: str | None) -> str:
    """A metric's or quantity's unit ("" for a ratio or an unknown name)."""
    q = _QUANTITIES.get(name or "")
    return q.unit if q is not None else ""


def heading(name: str | None) -> str:
    """A metric's label with its unit in parentheses, for axes and table columns: 'BBS (m/s)'."""
    return f"{label(name)} ({unit(name)})" if unit(name) else label(name)


def register(m: Metric) -> None:
    """Add a metric; ConfigError if its name is taken or its budget output is not the model's."""
    from rig.measure.model import OUTPUTS  # numpy: only when a metric is added

    if not m.name.isidentifier() or m.name in _QUANTITIES:
        raise ConfigError(f"metric name {m.name!r} is taken or not an identifier")
    if m.budget_output not in OUTPUTS:
        raise ConfigError(
            f"budget output {m.budget_output!r} is not one of the model's ({', '.join(OUTPUTS)})",
            source="metric",
        )
    low, high = m.limit_range
    if not low < high:
        raise ConfigError(f"limit range ({low:g}, {high:g}]: low must be below high")
    _QUANTITIES[m.name] = m
    _refresh()


def unregister(name: str) -> None:
    """Remove a metric `register` added (the built-in ones stay)."""
    if name in BUILTIN_METRICS or find(name) is None:
        raise ConfigError(f"{name!r} is not a registered metric that can be removed")
    del _QUANTITIES[name]
    _refresh()


@contextmanager
def registered(m: Metric) -> Iterator[Metric]:
    """`m` registered for the length of the block, removed after it (also on an error)."""
    register(m)
    try:
        yield m
    finally:
        unregister(m.name)

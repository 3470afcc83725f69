"""Control charts of a check standard: the pure maths (rig.core and numpy only).

Each check session (one `rig check` run) gives n hits of the metric. Three charts follow it:

- an individuals chart of the session means, warning limits at +-2 sigma and action limits at
  +-3 sigma; sigma is the moving range of the phase I means over d2 = 2/sqrt(pi) (1.128), because
  the session mean varies from session to session (ball, air, set-up) by more than the hits'
  spread within a session predicts: the within-session s / sqrt(n) would see repeatability only
  and put the limits too tight;
- an EWMA of the phase II session means, z_t = lambda x_t + (1 - lambda) z_(t-1), z_0 = mu0, with
  the exact (time-varying) limits mu0 +- k sigma sqrt(lambda / (2 - lambda) (1 - (1 - lambda)^(2t))),
  t counted from the first phase II session (lambda 0.2, k 3, the same sigma);
- an s-chart of the hits' spread within each session: sigma_w the phase I mean of s_i / c4(n_i)
  (unbiased; equal n: s-bar / c4), centre c4(n) sigma_w, limits B3(n) and B4(n) times that centre.

Phase I is the first M sessions (default 20): their centre and sigmas are the chart's; phase II
sessions are judged against them (phase I points are shown, not judged). With standard values
given (`standard=(centre, sigma)`, as for the model cross-check's standardised residuals, whose
centre 0 and sigma 1 the calibration states), there is no phase I: every point is judged, the EWMA
starts at the first. Signals: a phase II
mean beyond an action limit, an EWMA outside its limits, an s above its upper limit. A sigma of 0
(constant phase I data) makes the limits the centre itself: any departure from it signals.

`ewma_arl` gives the EWMA's average run length by the Markov-chain method of Brook and Evans
(1972) with the asymptotic limits: the design figure (about 560 in control for lambda 0.2, k 3).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from rig.core.errors import ParameterError

LAMBDA = 0.2  # the EWMA's weight (NIST/SEMATECH: 0.2-0.3)
K = 3.0  # the EWMA's limit width, in its own sigmas
PHASE_I = 20  # sessions that set the centre and the sigmas
D2 = 2.0 / math.sqrt(math.pi)  # E[moving range of two] / sigma, 1.128
WARNING, ACTION = 2.0, 3.0  # the individuals chart's limits, in sigmas

SIGMA_NOTE = (
    "sigma of the session means: moving range of the phase I means / 1.128 (it includes the "
    "between-session variation the within-session spread misses); "
    "s-chart: sigma_w = phase I mean of s / c4(n)"
)


def c4(n: int) -> float:
    """E[s] / sigma for a normal sample of n (n >= 2)."""
    if n < 2:
        raise ParameterError("n", n, "c4 needs at least 2 values")
    return math.sqrt(2.0 / (n - 1)) * math.exp(math.lgamma(n / 2.0) - math.lgamma((n - 1) / 2.0))


def b3_b4(n: int) -> tuple[float, float]:
    """The s-chart's factors for samples of n: LCL = B3 s-bar, UCL = B4 s-bar."""
    c = c4(n)
    spread = 3.0 * math.sqrt(1.0 - c * c) / c
    return max(0.0, 1.0 - spread), 1.0 + spread


@dataclass(frozen=True)
class Session:
    """One check session: its label (a run id), when, and its hits' values."""

    label: str
    values: tuple[float, ...]
    when: str = ""

    def __post_init__(self) -> None:
        if not self.values:
            raise ParameterError(f"session {self.label} values", "()", "a session needs at least one hit")
        for v in self.values:
            if not isinstance(v, int | float) or not math.isfinite(v):
                raise ParameterError(f"session {self.label} values", v, "not a finite number")

    @property
    def n(self) -> int:
        """The number of hits."""
        return len(self.values)

    @property
    def mean(self) -> float:
        """The hits' mean (about the first hit: equal hits give exactly their value)."""
        first = self.values[0]
        return first + math.fsum(v - first for v in self.values) / len(self.values)

    @property
    def s(self) -> float | None:
        """The hits' sample standard deviation (None for one hit)."""
        if len(self.values) < 2:
            return None
        m = self.mean
        return math.sqrt(math.fsum((v - m) ** 2 for v in self.values) / (len(self.values) - 1))


@dataclass(frozen=True)
class Signal:
    """An out-of-control signal: the rule, the session and the value against its limit."""

    rule: str  # "action limit", "EWMA", "s-chart"
    session: str
    index: int  # 1-based position of the session on the chart
    value: float
    limit: float

    @property
    def key(self) -> str:
        """What an acknowledgement names: the rule and the session."""
        return f"{self.rule}@{self.session}"

    def describe(self) -> str:
        """One line: which rule, which session, the value and the limit."""
        words = {
            "action limit": "session mean",
            "EWMA": "EWMA",
            "s-chart": "within-session s",
        }[self.rule]
        return (
            f"{self.rule}: session {self.index} (run {self.session[:12]}) {words} "
            f"{self.value:.6g} beyond {self.limit:.6g}"
        )


@dataclass(frozen=True)
class Point:
    """One session on the charts, with the limits it is judged against (None: phase I, or no chart)."""

    index: int
    session: str
    when: str
    n: int
    mean: float
    s: float | None
    phase: int  # 1 or 2
    ewma: float | None = None
    ewma_low: float | None = None
    ewma_high: float | None = None
    s_centre: float | None = None
    s_low: float | None = None
    s_high: float | None = None


@dataclass(frozen=True)
class Charts:
    """The three charts of one series of check sessions."""

    phase_i: int  # M, the sessions that set the limits
    sessions: int
    centre: float | None  # mu0 (None while phase I is incomplete)
    sigma: float | None  # of the session means (moving range)
    sigma_within: float | None  # of the hits within a session (None if no session has 2 hits)
    lam: float
    k: float
    points: tuple[Point, ...]
    signals: tuple[Signal, ...]
    notes: tuple[str, ...] = field(default_factory=tuple)
    given: bool = False  # centre and sigma given (standard values), not estimated in a phase I

    @property
    def ready(self) -> bool:
        """Whether phase I is complete (limits exist)."""
        return self.centre is not None

    def limits(self) -> dict[str, float] | None:
        """The individuals chart's limits (None while phase I is incomplete)."""
        if self.centre is None or self.sigma is None:
            return None
        c, s = self.centre, self.sigma
        return {
            "centre": c,
            "warning_low": c - WARNING * s,
            "warning_high": c + WARNING * s,
            "action_low": c - ACTION * s,
            "action_high": c + ACTION * s,
            "ewma_asymptotic_low": c - self.k * s * math.sqrt(self.lam / (2.0 - self.lam)),
            "ewma_asymptotic_high": c + self.k * s * math.sqrt(self.lam / (2.0 - self.lam)),
        }

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view: the design, the limits, every point and every signal."""
        return {
            "phase_i_sessions": self.phase_i,
            "sessions": self.sessions,
            "centre": self.centre,
            "sigma": self.sigma,
            "sigma_method": "standard values given" if self.given else SIGMA_NOTE,
            "sigma_within": self.sigma_within,
            "ewma": {
                "lambda": self.lam,
                "k": self.k,
                "limits": "exact (time-varying), t from the first phase II session",
            },
            "limits": self.limits(),
            "points": [asdict(p) for p in self.points],
            "signals": [{**asdict(s), "key": s.key, "text": s.describe()} for s in self.signals],
            "notes": list(self.notes),
        }


def build(
    sessions: Sequence[Session],
    *,
    phase_i: int = PHASE_I,
    lam: float = LAMBDA,
    k: float = K,
    standard: tuple[float, float] | None = None,
) -> Charts:
    """The individuals, EWMA and s charts of `sessions` (oldest first), phase I the first `phase_i`;
    with `standard` (centre, sigma) given, no phase I and every session judged."""
    if not isinstance(phase_i, int) or phase_i < 2:
        raise ParameterError("phase I sessions", phase_i, "must be a whole number of at least 2")
    if not 0.0 < lam <= 1.0:
        raise ParameterError("lambda", lam, "must lie in (0, 1]")
    if not 0.0 < k <= 6.0:
        raise ParameterError("k", k, "must lie in (0, 6]")
    means = [s.mean for s in sessions]
    notes: list[str] = []
    if standard is not None:
        centre, sigma = standard
        if not (math.isfinite(centre) and math.isfinite(sigma) and sigma > 0.0):
            raise ParameterError("standard (centre, sigma)", standard, "needs finite values, sigma above 0")
        phase_i = 0
        notes.append(
            f"standard values given: centre {centre:g}, sigma {sigma:g}; no phase I, every point judged"
        )
    elif len(sessions) < phase_i:
        notes.append(f"phase I: {len(sessions)} of {phase_i} sessions; no limits yet, nothing judged")
        shown = tuple(_point(i, s, 1) for i, s in enumerate(sessions))
        return Charts(phase_i, len(sessions), None, None, None, lam, k, shown, (), tuple(notes))
    else:
        first = means[:phase_i]
        centre = first[0] + math.fsum(m - first[0] for m in first) / phase_i  # equal means: exactly theirs
        sigma = math.fsum(abs(b - a) for a, b in itertools.pairwise(first)) / (phase_i - 1) / D2
    ratios = [s.s / c4(s.n) for s in sessions[:phase_i] if s.s is not None]
    sigma_w = math.fsum(ratios) / len(ratios) if ratios else None
    if sigma == 0.0:
        notes.append("phase I means do not vary (sigma 0): any departure from the centre signals")
    if sigma_w is None and standard is None:
        notes.append("no phase I session has two hits: no s-chart")
    points: list[Point] = []
    signals: list[Signal] = []
    z = centre
    for i, sess in enumerate(sessions):
        if i < phase_i:
            points.append(_point(i, sess, 1, sigma_w))
            continue
        t = i - phase_i + 1
        z += lam * (sess.mean - z)  # lam x + (1 - lam) z, exact for x = z
        half = k * sigma * math.sqrt(lam / (2.0 - lam) * (1.0 - (1.0 - lam) ** (2 * t)))
        point = _point(i, sess, 2, sigma_w, z, centre - half, centre + half)
        points.append(point)
        signals += _judged(point, centre, sigma)
    return Charts(
        phase_i, len(sessions), centre, sigma, sigma_w, lam, k, tuple(points), tuple(signals), tuple(notes),
        standard is not None,
    )  # fmt: skip


def _point(
    i: int,
    sess: Session,
    phase: int,
    sigma_w: float | None = None,
    z: float | None = None,
    low: float | None = None,
    high: float | None = None,
) -> Point:
    s_centre = s_low = s_high = None
    if sigma_w is not None and sess.n >= 2:
        b3, b4 = b3_b4(sess.n)
        s_centre = c4(sess.n) * sigma_w
        s_low, s_high = b3 * s_centre, b4 * s_centre
    return Point(
        i + 1, sess.label, sess.when, sess.n, sess.mean, sess.s, phase, z, low, high, s_centre, s_low, s_high
    )


def _judged(p: Point, centre: float, sigma: float) -> list[Signal]:
    """The signals of one phase II point (strictly beyond a limit)."""
    found = []
    low, high = centre - ACTION * sigma, centre + ACTION * sigma
    if not low <= p.mean <= high:
        found.append(Signal("action limit", p.session, p.index, p.mean, high if p.mean > high else low))
    z, low_z, high_z = p.ewma, p.ewma_low, p.ewma_high
    if z is not None and low_z is not None and high_z is not None and not low_z <= z <= high_z:
        found.append(Signal("EWMA", p.session, p.index, z, high_z if z > high_z else low_z))
    if p.s is not None and p.s_high is not None and p.s > p.s_high:
        found.append(Signal("s-chart", p.session, p.index, p.s, p.s_high))
    return found


def ewma_arl(shift: float, lam: float = LAMBDA, k: float = K, states: int = 201) -> float:
    """The EWMA's average run length for a mean shifted by `shift` sigmas of the charted value,
    starting at the centre, asymptotic limits (Brook and Evans's Markov chain, `states` cells)."""
    q, start = _ewma_chain(shift, lam, k, states)
    arl = np.linalg.solve(np.eye(states) - q, np.ones(states))
    return float(arl[start])


def ewma_run_length_quantile(
    shift: float, p: float, lam: float = LAMBDA, k: float = K, states: int = 201
) -> int:
    """The smallest n with P(run length <= n) >= p (the same chain as ewma_arl)."""
    if not 0.0 < p < 1.0:
        raise ParameterError("p", p, "must lie in (0, 1)")
    q, start = _ewma_chain(shift, lam, k, states)
    alive = np.zeros(states)
    alive[start] = 1.0
    for n in range(1, 1_000_000):
        alive = alive @ q
        if 1.0 - alive.sum() >= p:
            return n
    raise ParameterError("shift", shift, "run length beyond a million sessions")


def _ewma_chain(shift: float, lam: float, k: float, states: int) -> tuple[Any, int]:
    """The transient matrix of the EWMA's Markov chain (in units of sigma) and the start cell."""
    from math import erf, sqrt

    if not math.isfinite(shift):
        raise ParameterError("shift", shift, "not a finite number")
    if states % 2 == 0 or states < 11:
        raise ParameterError("states", states, "must be an odd number of at least 11")
    h = k * math.sqrt(lam / (2.0 - lam))
    width = 2.0 * h / states
    mids = -h + width * (np.arange(states) + 0.5)
    cdf = np.vectorize(lambda x: 0.5 * (1.0 + erf(x / sqrt(2.0))))
    # from cell i, z' = (1 - lam) m_i + lam x lies in cell j when x lies in [a, b) below
    lower = (mids[None, :] - width / 2.0 - (1.0 - lam) * mids[:, None]) / lam - shift
    upper = (mids[None, :] + width / 2.0 - (1.0 - lam) * mids[:, None]) / lam - shift
    return cdf(upper) - cdf(lower), states // 2

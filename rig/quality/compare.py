"""Results of two labs or rigs paired bat by bat, and a bat's retests, scored by E_n and z (scores).

A result is a finished run's mean and expanded U (the `runs_summary` view's row). Two sources are
paired by bat id and procedure (the procedure fixes the metric), the newest result of each side;
within one source, each retest of a bat under a procedure is paired with the result before it
(ISO/IEC 17025 7.7.1: retesting retained items). Pure: rows in, scores out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from rig.core.errors import ParameterError
from rig.quality import CHECK_KIND
from rig.quality.scores import Robust, Score, algorithm_a, score


@dataclass(frozen=True)
class Result:
    """One finished run's result: the bat, the procedure, mean +- U (expanded, coverage k)."""

    bat_id: str
    procedure: str
    mean: float
    U: float
    k: float | None
    run_id: str
    rig: str | None
    started_utc: str

    def to_json(self) -> dict[str, Any]:
        return {
            "run_id": self.run_id,
            "rig": self.rig,
            "started_utc": self.started_utc,
            "mean": self.mean,
            "U": self.U,
            "k": self.k,
        }


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


def results(rows: Iterable[Mapping[str, Any]]) -> list[Result]:
    """The rows (runs_summary's columns) that hold a result: a finished run with a finite mean and
    a U above zero, in the order of their start."""
    out = []
    for row in rows:
        mean, big_u = _number(row.get("mean")), _number(row.get("expanded_uncertainty"))
        if row.get("status") != "finished" or mean is None or big_u is None or big_u <= 0:
            continue
        out.append(
            Result(
                bat_id=str(row.get("bat_id")),
                procedure=str(row.get("procedure")),
                mean=mean,
                U=big_u,
                k=_number(row.get("k")),
                run_id=str(row.get("run_id")),
                rig=None if row.get("rig") is None else str(row.get("rig")),
                started_utc=str(row.get("started_utc") or ""),
            )
        )
    return sorted(out, key=lambda r: (r.started_utc, r.run_id))


@dataclass(frozen=True)
class Pair:
    """A bat's two results under one procedure: x (scored) and X (the reference)."""

    x: Result
    ref: Result


def paired(a: Sequence[Result], b: Sequence[Result]) -> list[Pair]:
    """Bats tested in both (same bat id and procedure), each side's newest result, by bat."""
    newest_a = {(r.bat_id, r.procedure): r for r in a}  # sorted by start: the last one wins
    newest_b = {(r.bat_id, r.procedure): r for r in b}
    return [Pair(newest_a[key], newest_b[key]) for key in sorted(newest_a.keys() & newest_b.keys())]


def retests(rs: Sequence[Result]) -> list[Pair]:
    """Each retest (same bat id and procedure, tested again) with the result before it as X; check
    runs on the reference bat are not retests (their control charts follow them: rig check chart)."""
    last: dict[tuple[str, str], Result] = {}
    out = []
    for r in rs:
        if r.procedure == CHECK_KIND:
            continue
        key = (r.bat_id, r.procedure)
        if key in last:
            out.append(Pair(r, last[key]))
        last[key] = r
    return sorted(out, key=lambda p: (p.x.bat_id, p.x.procedure, p.x.started_utc))


@dataclass(frozen=True)
class SigmaPt:
    """The sigma_pt z is scored with: given, or Algorithm A's s* of the differences; else why not."""

    value: float | None
    source: str  # "given", "algorithm A" or "none"
    robust: Robust | None = None
    why_not: str | None = None


def sigma_pt(pairs: Sequence[Pair], given: float | None) -> SigmaPt:
    """The user's sigma_pt, else the robust SD of the differences x - X; with too few (or no spread),
    none, and the one line saying why."""
    if given is not None:
        if not (math.isfinite(given) and given > 0):
            raise ParameterError("--sigma-pt", given, "must be a finite number greater than zero")
        return SigmaPt(given, "given")
    try:
        robust = algorithm_a([p.x.mean - p.ref.mean for p in pairs], "differences")
    except ParameterError as exc:
        return SigmaPt(None, "none", why_not=f"no z: {exc.reason} ({len(pairs)} bats paired)")
    return SigmaPt(robust.sd, "algorithm A", robust)


@dataclass(frozen=True)
class Scored:
    """A pair and its scores."""

    pair: Pair
    score: Score


@dataclass(frozen=True)
class Comparison:
    """Every pair scored, and the sigma_pt of the z scores."""

    rows: list[Scored]
    sigma: SigmaPt
    notes: list[str] = field(default_factory=list)


def compare(pairs: Sequence[Pair], given_sigma: float | None = None, z: bool = True) -> Comparison:
    """E_n of every pair, and z where a sigma_pt is given or can be estimated (`z` False: E_n only,
    unless a sigma_pt is given)."""
    sigma = (
        sigma_pt(pairs, given_sigma)
        if z or given_sigma is not None
        else SigmaPt(None, "none", why_not="no z: a retest's z needs --sigma-pt (E_n compares it with its U)")
    )
    rows = [Scored(p, score(p.x.mean, p.x.U, p.ref.mean, p.ref.U, sigma.value)) for p in pairs]
    return Comparison(rows, sigma, [sigma.why_not] if sigma.why_not else [])

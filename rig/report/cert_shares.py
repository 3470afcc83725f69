"""The result's u² split into its terms: the measurement inputs, the hits' scatter, the ball's terms.

The certificate's budget table and its "largest contribution" are on the result's u (the verdict's
u, its U = k u), not on the measurement budget alone: in a run with a lot's ball terms the ball can
be almost all of it. Every term is a variance in the metric's unit, from the record alone:

- each input of the recorded model budget: its share of the budget's u², times that u² and the
  registry's u_scale squared (rig.report.cert_plots.budget_scale);
- the hits' observed scatter beyond the modelled random inputs (rig.measure.uncertainty
  u_with_scatter: the measurement's u² less the model budget's);
- the ball's terms (rig.protocols.ball_terms): wear, the lab's air, the spread between balls, the
  ratio g; a BPF's (rig.protocols.bpf_verdict) are the spread and g over the COR, the COR's test,
  and the air and wear shared by the hits and the COR;
- whatever the record's u holds beyond these (an older record's combination): "others".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

_BALL_WHAT = {
    "u_wear": "the ball's wear within each ball (ball term)",
    "u_conditions": "the lab's air against the ball's nominal (ball term)",
    "u_spread": "spread between the lot's balls (ball term)",
    "u_ratio": "the model ratio g on the ball corrections (ball term)",
}
_BPF_WHAT = {
    "u_from_ball_cor": "the lot's COR: its ball-cor test (u(COR), correlated across the hits)",
    "u_shared_air": "the lab's air, shared by the hits and the lot's COR (ball term)",
    "u_shared_wear": "the wear per hit, shared by the hits and the lot's COR (ball term)",
}
SCATTER = "scatter"


@dataclass(frozen=True)
class Term:
    """One term of the result's u²: its key, its variance (metric unit²), and whether an input of
    the measurement budget (its u and kind are in the budget's inputs)."""

    key: str
    variance: float
    measurement_input: bool = False


def _num(x: Any) -> float | None:
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else None


def what(key: str) -> str | None:
    """The words for a term that is not a measurement input, None for an input."""
    if key == SCATTER:
        return "the hits' observed scatter beyond the modelled random inputs"
    return _BALL_WHAT.get(key) or _BPF_WHAT.get(key)


def result_terms(v: dict[str, Any], out_b: dict[str, Any], scale: float) -> tuple[list[Term], float] | None:
    """The terms of the verdict `v`'s u² and that u² (None without a u); `out_b` is the recorded
    budget output the metric scales from by `scale`."""
    u = _num(v.get("u"))
    u_b = _num(out_b.get("u"))
    if u is None or u_b is None or u <= 0:
        return None
    model = (scale * u_b) ** 2
    terms = [
        Term(k, share * model, True)
        for k, share in (out_b.get("contributions") or {}).items()
        if isinstance(share, int | float)
    ]
    ball: dict[str, Any] = v["ball"] if isinstance(v.get("ball"), dict) else {}
    bpf: dict[str, Any] | None = v["bpf"] if isinstance(v.get("bpf"), dict) else None
    if bpf is not None:  # BPF: every BBCOR term over the COR; the COR's and the shared terms as they are
        cor = _num(bpf.get("ball_cor"))
        hits = _num(bpf.get("u_bbcor_hits"))
        over = 1.0 / cor if cor else 0.0
        if hits is not None:
            terms.append(Term(SCATTER, max(0.0, (over * hits) ** 2 - model)))
        terms += [Term(k, (over * x) ** 2) for k in ("u_spread", "u_ratio") if (x := _num(ball.get(k)))]
        terms += [Term(k, x * x) for k in _BPF_WHAT if (x := _num(bpf.get(k)))]
    else:
        measured = _num(ball.get("u_measurement")) if ball else u
        if measured is not None:
            terms.append(Term(SCATTER, max(0.0, measured**2 - model)))
        terms += [Term(k, x * x) for k in _BALL_WHAT if (x := _num(ball.get(k)))]
    rest = u * u - sum(t.variance for t in terms)
    if rest > 1e-6 * u * u:
        terms.append(Term("others", rest))
    return sorted((t for t in terms if t.variance > 0), key=lambda t: -t.variance), u * u

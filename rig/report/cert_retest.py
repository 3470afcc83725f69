"""Retesting a retained item (ISO/IEC 17025 7.7.1): a bat certified again under the same procedure is
compared with its earlier result by E_n, with both expanded uncertainties (rig.quality.scores).

When a certification is created, `earlier_result` finds the bat's newest finished result under the
procedure in the store, and the run records it in its RunCreated entry (meta `retest_of`): the
comparison is part of the hash-chained record, and its certificate never changes with what the
store holds later. `retest_blocks` is the certificate's section, from the record alone (nothing for
a first test, nor for a run recorded before retests were).
"""

from __future__ import annotations

import math
from typing import Any

from rig.core import events as ev
from rig.quality.scores import EN_LIMIT, assess_en, en_score
from rig.report.cert_doc import Block, Heading, Para, Table
from rig.store import Store

RETEST_KEY = "retest_of"  # RunCreated's meta key; the run record's key


def _finite(value: Any) -> float | None:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None


def earlier_result(store: Store, procedure: str, bat_id: str) -> dict[str, Any] | None:
    """The bat's newest finished result under `procedure` in `store` (run, start, mean, U, k, verdict),
    or None if it has none: a result has a finite mean and a U above zero."""
    runs = [r for r in store.runs() if (r.procedure, r.bat_id, r.status) == (procedure, bat_id, "finished")]
    for run in reversed(runs):
        finished = store.entries(run.run_id, kinds=[ev.RUN_FINISHED])
        if not finished:
            continue
        payload = finished[-1].payload
        mean, big_u = _finite(payload.get("mean")), _finite(payload.get("U"))
        if mean is None or big_u is None or big_u <= 0:
            continue
        return {
            "run_id": run.run_id,
            "started_utc": run.started_utc,
            "mean": mean,
            "U": big_u,
            "k": _finite(payload.get("coverage_k")),
            "verdict": payload.get("verdict"),
        }
    return None


def retest_meta(store: Store, procedure: str, bat_id: str) -> dict[str, Any]:
    """What a new certification's RunCreated records of the bat's earlier result ({} if none)."""
    earlier = earlier_result(store, procedure, bat_id)
    return {} if earlier is None else {RETEST_KEY: earlier}


def retest_blocks(record: dict[str, Any]) -> list[Block]:
    """The retest section: the earlier result and this one, E_n and what it says; [] for a first test
    or a run without a result (an interrupted or ended run's document shows no earlier result)."""
    earlier = record.get(RETEST_KEY)
    verdict = record.get("verdict") or {}
    x, u_x = _finite(verdict.get("mean")), _finite(verdict.get("U"))
    if not isinstance(earlier, dict) or x is None or u_x is None or u_x <= 0:
        return []
    ref, u_ref = _finite(earlier.get("mean")), _finite(earlier.get("U"))
    places = _places(u_x, u_ref)
    blocks: list[Block] = [
        Heading("Retest of a retained item"),
        Para(
            f"This bat was certified under this procedure before, in run {earlier.get('run_id', '?')} "
            f"(started {earlier.get('started_utc') or '?'} UTC); the two results are compared by "
            f"E_n = (x - X) / sqrt(U_x^2 + U_X^2), satisfactory when |E_n| <= {EN_LIMIT:g} (ISO 13528)."
        ),
        Table(
            ("result", "mean", "U"),
            (
                ("earlier result (X)", _num(ref, places), _num(u_ref, places)),
                ("this result (x)", _num(x, places), _num(u_x, places)),
            ),
        ),
    ]
    if ref is None or u_ref is None or u_ref <= 0:
        blocks.append(Para("No E_n: the earlier result has no expanded uncertainty to compare."))
        return blocks
    en = en_score(x, u_x, ref, u_ref)
    blocks.append(Para(f"E_n = {en:+.2f}: {assess_en(en)} (difference x - X = {x - ref:+.4g})."))
    return blocks


def _places(*uncertainties: float | None) -> int:
    """Decimal places that give the smaller U two significant digits (GUM 7.2.6), as the verdict does."""
    sizes = [u for u in uncertainties if u is not None and u > 0]
    return max(0, 1 - math.floor(math.log10(min(sizes)))) if sizes else 6


def _num(value: float | None, places: int) -> str:
    return "—" if value is None else f"{value:.{places}f}"

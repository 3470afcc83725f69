"""Population rows from the record store: registered bats, their modal results and measured runs.

For each registered bat: hoop_hz from its registered spec, else from its latest ModalResult
entry; first bending frequency from that ModalResult; BESR, BBS and BBCOR the means over the
valid hits (purpose 'valid', at the run's chosen location) of every finished run of the bat, each
metric as rig.measure.metrics computed it per shot (ShotMeasured); location_in the mean over those
runs of the chosen location (RunFinished). u_<metric> for the metric a run certified: the
result's standard uncertainty (its U / k, the `u` RunFinished records); over several runs of a
bat the mean of their u (the rig's systematic parts, common to the runs, dominate, so the runs'
u are not averaged down as if independent). Bats with no hoop frequency are left out, with a note.

Check runs (`rig check`, kind `check`) are not read: they strike the lab's reference bat again and
again to watch the rig, and a bat is certified once. A bat whose only runs are check runs (the
reference bat) is left out, with a note.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

from rig.core import events as ev
from rig.core.run_state import fold
from rig.modal.link import latest_modal_result
from rig.population.dataset import METRICS, PopulationBat
from rig.store import Store


@dataclass(frozen=True)
class RunConditions:
    """What a certified run fired: its procedure's inbound speed (m/s) and ball mass (kg)."""

    speed_m_s: float
    ball_mass_kg: float


def _conditions(setup: dict[str, Any] | None) -> RunConditions | None:
    procedure = (setup or {}).get("procedure") or {}
    speed, ball = procedure.get("target_speed_m_s"), procedure.get("ball") or {}
    mass = ball.get("mass_kg")
    if not isinstance(speed, int | float) or not isinstance(mass, int | float):
        return None
    return RunConditions(float(speed), float(mass))


def _run_metrics(
    store: Store, run_id: str, standard: str | None = None, conditions: list[RunConditions] | None = None
) -> tuple[dict[str, list[float]], float | None]:
    kinds = [ev.SHOT_REQUESTED, ev.SHOT_MEASURED, ev.SHOT_REJECTED, ev.SHOT_OVERRULED, ev.RUN_FINISHED]
    kinds += [ev.RUN_STARTED] if standard is not None else []
    state = fold(ev.parse_log(store.entries(run_id, kinds=kinds)))
    out: dict[str, list[float]] = defaultdict(list)
    v = state.verdict
    if v is None or (standard is not None and v.metric != standard):
        return out, None
    if conditions is not None:
        found = _conditions(state.setup)
        if found is not None:
            conditions.append(found)
    location = v.location_in
    for shot in state.shots:
        o = shot.outcome
        if not shot.valid or o is None or shot.purpose != "valid" or shot.location_in != location:
            continue
        metrics: dict[str, Any] = o.metrics or {}
        for name in METRICS:
            if isinstance(metrics.get(name), int | float):
                out[name].append(float(metrics[name]))
    if out and isinstance(location, int | float):
        out["location_in"].append(float(location))  # once per run: the bat's mean chosen location
    if v.metric in METRICS and out.get(v.metric) and isinstance(v.u, int | float):
        out[f"u_{v.metric}"].append(float(v.u))  # once per run: the certified result's standard uncertainty
    return out, float(v.moi_kgm2) if isinstance(v.moi_kgm2, int | float) else None


def bats_from_store(
    store: Store, standard: str | None = None, conditions: list[RunConditions] | None = None
) -> tuple[list[PopulationBat], list[str]]:
    """The store's bats as population rows, and notes on those left out.

    `standard`: only the runs that certified this metric (a BPF, a USA Softball BBS: their shots'
    BBCOR at the standard's speed), each run's speed and ball mass appended to `conditions`; a bat
    with no such run is left out."""
    per_bat: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    mois: dict[str, list[float]] = defaultdict(list)
    checked: set[str] = set()
    tested: set[str] = set()
    for run in store.runs():
        (checked if run.procedure == ev.CHECK_KIND else tested).add(run.bat_id)
        if run.status != "finished" or run.procedure == ev.CHECK_KIND:
            continue
        values, moi = _run_metrics(store, run.run_id, standard, conditions)
        for name, vals in values.items():
            per_bat[run.bat_id][name] += vals
        if moi is not None:
            mois[run.bat_id].append(moi)
    bats, notes = [], []
    for bat_id, spec in sorted(store.bats().items()):
        if bat_id in checked - tested:
            notes.append(f"bat {bat_id}: a check standard (only check runs, rig check): left out")
            continue
        modal = latest_modal_result(store, bat_id)
        hoop = spec.get("hoop_hz") or (modal or {}).get("hoop_hz")
        if hoop is None:
            notes.append(f"bat {bat_id}: no hoop frequency (bat file or modal result): left out")
            continue
        bending = (modal or {}).get("bending_hz") or []
        metrics = {name: statistics.fmean(v) for name, v in per_bat[bat_id].items() if v}
        if standard is not None and not metrics:
            notes.append(f"bat {bat_id}: no certified {standard} run: left out")
            continue
        moi = spec.get("moi_kgm2") or (statistics.fmean(mois[bat_id]) if mois[bat_id] else None)
        bats.append(
            PopulationBat(
                bat_id=bat_id,
                barrel=spec["barrel"],
                hoop_hz=float(hoop),
                bending_hz=float(bending[0]) if bending else None,
                length_in=spec.get("length_in"),
                weight_oz=spec.get("weight_oz"),
                moi_kgm2=moi,
                source=f"store {store.path.name}",
                **metrics,
            )
        )
    return bats, notes

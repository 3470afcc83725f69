"""Live progress of a certification on the terminal (a subscriber: it only listens)."""

from __future__ import annotations

from typing import Any

from rich.markup import escape

from rig.core import events as ev
from rig.core.events import RunEvent
from rig.report.terminal import console


class LiveConsole:
    """Prints one line per step as events arrive, to stderr (stdout stays free for JSON)."""

    def __init__(self, quiet: bool = False) -> None:
        self.console = console(stderr=True, highlight=False)
        self.quiet = quiet

    def __call__(self, event: RunEvent) -> None:
        line = self._line(event.kind, event.data)
        if line and (not self.quiet or event.kind == ev.RIG_NAMED):  # the rig and its signature: always
            self.console.print(line)

    def _line(self, kind: str, d: dict[str, Any]) -> str | None:
        if kind == ev.RIG_NAMED:
            rig = f"rig {d['name']}" + (" (simulated)" if d["simulated"] else "")
            return escape(rig + (f": {d['signing']}" if d["signing"] else ""))
        if kind == ev.RUN_STARTED:
            p, b = d["procedure"], d["bat"]
            if "target" in b:  # a ball test: the clamp holds a rigid target, the cannon a lot's balls
                lot = d.get("lot") or {}
                return (
                    f"[bold]{p['name']}[/] of lot {lot.get('id')} on the {b['target']} ({b['id']}); "
                    f"edition: {p['edition']}"
                )
            return (
                f"[bold]{p['name']}[/] on bat {b['id']} ({b['length_in']:g} in, {b['weight_oz']:g} oz, "
                f"{b['barrel']}); edition: {p['edition']}"
            )
        if kind == ev.RUN_RESUMED:
            return f"resumed after {d['shots_so_far']} shot(s)"
        if kind == ev.ENVIRONMENT_CHECKED:
            ok = "ok" if d["ok"] else "[red]OUT OF LIMITS[/]"
            return f"lab {d['temperature_c']:.1f} C, {d['humidity_pct']:.0f} % RH: {ok}"
        if kind == ev.MOI_MEASURED:
            return f"MOI about the pivot {d['moi_kgm2']:.5f} kg m^2 ({d['source']})"
        if kind == ev.LOCATION_SET:
            q = d["impact_from_pivot_m"]
            return f"impact point {d['from_barrel_end_in']:g} in from the tip (Q = {q:.4f} m)"
        if kind == ev.SHOT_MEASURED:
            return (
                f"  shot {d['index']:>2} valid   v_in {d['inbound_speed_m_s']:.2f}  v_out "
                f"{d['rebound_speed_m_s']:.2f} m/s  {d['metric_name']} {d['metric']:.4f} +- {d['u']:.4f}"
            )
        if kind == ev.SHOT_REJECTED:
            why = "; ".join(r["code"] for r in d.get("reasons", []) if r.get("invalidates", True))
            return f"  shot {d['index']:>2} [yellow]invalid[/] ({why}): re-shoot"
        if kind == ev.SHOT_LOST:
            return f"  shot {d['index']:>2} [red]lost[/]: {d['reason']}"
        if kind == ev.BALL_REPLACED:
            return f"ball replaced: ball {d.get('ball') or d['ball_number']}"
        if kind == ev.LOCATION_CHOSEN:
            edge = "" if d.get("bracketed", True) else f" (NOT bracketed; accepted by {d.get('accepted_by')})"
            return f"location of maximum performance: {d['from_barrel_end_in']:g} in from the tip{edge}"
        if kind == ev.SCAN_EXTENDED:
            return f"scan extended to {d['from_barrel_end_in']:g} in: {d['reason']}"
        if kind == ev.RIG_CHECKED:
            return f"rig checked by {d['who']}: {d['why']} (re-shoot budget starts again)"
        if kind == ev.RUN_INTERRUPTED:
            return f"[red]interrupted[/]: {d['reason']}"
        if kind == ev.RUN_FINISHED and "mean" in d:
            return (
                f"[bold]{d['verdict']}[/]: {d['metric']} {d['mean']:.4f} +- {d['U']:.4f} "
                f"(k={d['coverage_k']:g}) against {d['limit']:g}"
            )
        return None

    def summary(self, outcome: Any) -> None:
        """The verdict and the model cross-check, on stdout."""
        out = console(highlight=False)
        v = outcome.verdict
        if not v:
            return
        out.print(
            f"run {outcome.run_id}: [bold]{v['verdict']}[/]"
            + (f" ({v.get('zone')})" if v.get("zone") else "")
        )
        if "mean" in v:
            out.print(
                f"  {v['metric']} = {v['mean']:.4f}, U = {v['U']:.4f} (k = {v['coverage_k']:g}), "
                f"limit {v['limit']:g}; {v['decision_rule']}"
            )
            cc = v.get("cross_check") or {}
            if cc.get("predicted") is not None:
                out.print(
                    f"  model at {cc['hoop_hz'] or 'rigid'} Hz predicts {cc['predicted']:.4f}: {cc['note']}"
                )
        elif v.get("reason"):
            out.print(f"  {v['reason']}")

    def close(self) -> None:
        """Nothing to release; kept for symmetry with richer displays."""

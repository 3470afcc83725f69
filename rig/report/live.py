"""Live progress of a certification on the terminal (a subscriber: it only listens)."""

from __future__ import annotations

from typing import Any

from rich.markup import escape

from rig.core import events as ev
from rig.core.events import RunEvent
from rig.core.outcomes import RunVerdict
from rig.report.terminal import console


class LiveConsole:
    """Prints one line per step as events arrive, to stderr (stdout stays free for JSON)."""

    def __init__(self, quiet: bool = False) -> None:
        self.console = console(stderr=True, highlight=False)
        self.quiet = quiet

    def __call__(self, event: RunEvent) -> None:
        line = _line(event)
        if line and (not self.quiet or event.kind == ev.RIG_NAMED):  # the rig and its signature: always
            self.console.print(line)

    def summary(self, outcome: Any) -> None:
        """The verdict and the model cross-check, on stdout."""
        out = console(highlight=False)
        v: RunVerdict | None = outcome.verdict
        if v is None:
            return
        out.print(f"run {outcome.run_id}: [bold]{v.verdict}[/]" + (f" ({v.zone})" if v.zone else ""))
        if v.mean is not None:
            out.print(
                f"  {v.metric} = {v.mean:.4f}, U = {v.U:.4f} (k = {v.coverage_k:g}), "
                f"limit {v.limit:g}; {v.decision_rule}"
            )
            cc = v.cross_check or {}
            if cc.get("predicted") is not None:
                hoop = f"{cc['hoop_hz']:.0f}" if cc.get("hoop_hz") else "rigid"
                out.print(f"  model at {hoop} Hz predicts {cc['predicted']:.4f}: {cc['note']}")
            if (v.reason or "").startswith("after accelerated break-in"):
                out.print(f"  {v.reason}")
        elif v.reason:
            out.print(f"  {v.reason}")

    def close(self) -> None:
        """Nothing to release; kept for symmetry with richer displays."""


def _line(e: RunEvent) -> str | None:
    """The event's line (None: nothing to say)."""
    match e:
        case ev.RigNamed():
            rig = f"rig {e.name}" + (" (simulated)" if e.simulated else "")
            return escape(rig + (f": {e.signing}" if e.signing else ""))
        case ev.RunStarted():
            p, b = e.procedure, e.bat
            if "target" in b:  # a ball test: the clamp holds a rigid target, the cannon a lot's balls
                lot = e.lot or {}
                return (
                    f"[bold]{p['name']}[/] of lot {lot.get('id')} on the {b['target']} ({b['id']}); "
                    f"edition: {p['edition']}"
                )
            return (
                f"[bold]{p['name']}[/] on bat {b['id']} ({b['length_in']:g} in, {b['weight_oz']:g} oz, "
                f"{b['barrel']}); edition: {p['edition']}"
            )
        case ev.RunResumed():
            return f"resumed after {e.shots_so_far} shot(s)"
        case ev.EnvironmentChecked():
            ok = "ok" if e.ok else "[red]OUT OF LIMITS[/]"
            return f"lab {e.temperature_c:.1f} C, {e.humidity_pct:.0f} % RH: {ok}"
        case ev.MoiMeasured():
            return f"MOI about the pivot {e.result.moi_kgm2:.5f} kg m^2 ({e.result.source})"
        case ev.LocationSet():
            return (
                f"impact point {e.from_barrel_end_in:g} in from the tip (Q = {e.impact_from_pivot_m:.4f} m)"
            )
        case ev.ShotEvaluated() if e.valid:
            o = e.outcome
            return (
                f"  shot {e.index:>2} valid   v_in {o.inbound_speed_m_s:.2f}  v_out "
                f"{o.rebound_speed_m_s:.2f} m/s  {o.metric_name} {o.metric:.4f} +- {o.u:.4f}"
            )
        case ev.ShotEvaluated():
            why = "; ".join(r["code"] for r in e.outcome.reasons if r.get("invalidates", True))
            return f"  shot {e.index:>2} [yellow]invalid[/] ({why}): re-shoot"
        case ev.ShotLost():
            return f"  shot {e.index:>2} [red]lost[/]: {e.reason}"
        case ev.BallReplaced():
            return f"ball replaced: ball {e.ball or e.ball_number}"
        case ev.LocationChosen():
            edge = "" if e.bracketed in (True, None) else f" (NOT bracketed; accepted by {e.accepted_by})"
            return f"location of maximum performance: {e.from_barrel_end_in:g} in from the tip{edge}"
        case ev.ScanExtended():
            return f"scan extended to {e.from_barrel_end_in:g} in: {e.reason}"
        case ev.RigChecked():
            return f"rig checked by {e.who}: {e.why} (re-shoot budget starts again)"
        case ev.CompressionMeasured():
            return (
                f"barrel compression at {e.location_in:g} in: {e.force_lbf:.1f} lbf at "
                f"{e.displacement_in:.3f} in (stage {e.stage})"
            )
        case ev.BarrelRolled():
            how = "by script" if e.given == ev.BY_SCRIPT else "answered at the prompt"
            hoop = "" if e.hoop_hz is None else f"; hoop {e.hoop_hz:.0f} Hz"
            return escape(f"rolled {e.depth_in:g} in x {e.passes} by {e.who} ({how}){hoop}")
        case ev.AbiStageMeasured():
            r = e.result
            return f"stage {e.stage}: {r['metric']} {r['mean']:.4f} +- {r['U']:.4f}: {r['verdict']}"
        case ev.RunInterrupted():
            return f"[red]interrupted[/]: {e.reason}"
        case ev.RunFinished() if e.result.mean is not None:
            v = e.result
            return (
                f"[bold]{v.verdict}[/]: {v.metric} {v.mean:.4f} +- {v.U:.4f} "
                f"(k={v.coverage_k:g}) against {v.limit:g}"
            )
    return None

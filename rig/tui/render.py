"""Text renderings of the live run: panels, sparklines and a gauge (no plotting library).

Each function takes the folded state and returns a rich Text that fits a panel about 36
columns wide, so the whole run screen fits an 80x24 terminal.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from rich.text import Text

from rig.core.devices import CannonState, CannonStatus, GateConfig
from rig.core.events import Verdict

if TYPE_CHECKING:  # the set-up screen draws the interlocks without the run's fold
    from rig.tui.live import LiveRun, LiveShot

BLOCKS = "▁▂▃▄▅▆▇█"
SHOT_STATUS = {
    "requested": ("firing...", "yellow"),
    "fired": ("measuring...", "yellow"),
    "valid": ("VALID", "bold green"),
    "invalid": ("INVALID", "bold yellow"),
    "lost": ("LOST", "bold red"),
}
PURPOSE = {"valid": "hit"}  # a shot for the result: "valid" before its status read like a verdict
STATE_STYLE = {
    CannonState.SAFE: "green",
    CannonState.ARMED: "bold yellow",
    CannonState.FIRED: "yellow",
    CannonState.FAULT: "bold red",
}


def sparkline(values: Sequence[float | None], lo: float, hi: float) -> str:
    """One block per value scaled to [lo, hi]; None (not measured yet) shows as a dot."""
    out = []
    for v in values:
        if v is None:
            out.append("·")
            continue
        f = 0.5 if hi <= lo else min(max((v - lo) / (hi - lo), 0.0), 1.0)
        out.append(BLOCKS[round(f * (len(BLOCKS) - 1))])
    return "".join(out)


def gauge(mean: float, limit: float, big_u: float = 0.0, width: int = 24) -> Text:
    """A bar from 0.8 x limit to 1.1 x limit: the mean filled, the guard band shaded, the limit marked."""
    lo, hi = 0.8 * limit, 1.1 * limit

    def cell(v: float) -> int:
        return min(max(round((v - lo) / (hi - lo) * width), 0), width)

    at_mean, at_guard, at_limit = cell(mean), cell(mean + big_u), min(cell(limit), width - 1)
    style = "green" if mean + big_u <= limit else "red"
    text = Text()
    for i in range(width):
        if i == at_limit:
            text.append("│", style="bold red")
        elif i < at_mean:
            text.append("█", style=style)
        elif i < at_guard:
            text.append("▒", style=style)
        else:
            text.append("·", style="dim")
    return text


def interlock_text(status: CannonStatus) -> Text:
    """door / clamp / estop: 'ok' in green when closed, 'OPEN' in red when not."""
    text = Text()
    loop = status.interlocks
    for name, closed in (("door", loop.door), ("clamp", loop.clamp), ("estop", loop.estop)):
        text.append(f"{name} ")
        text.append("ok" if closed else "OPEN", style="green" if closed else "bold white on red")
        text.append("  " if name != "estop" else "")
    return text


def cannon_panel(r: LiveRun) -> Text:
    """Cannon state and pressure, the interlocks, the lab air."""
    text = Text()
    st = r.cannon
    if st is None and r.cannon_note:  # a stale pressure is no safety display: say it is unknown
        text.append("UNKNOWN", style="bold yellow")
        text.append(f" {r.cannon_note}\n")
    elif st is None:
        text.append(r.cannon_error or "status not read yet", style="red" if r.cannon_error else "dim")
        text.append("\n\n")
    else:
        text.append(f"{st.state.value:<6}", style=STATE_STYLE.get(st.state, ""))
        text.append(f" {st.pressure_kpa:6.1f} / {st.setpoint_kpa:.1f} kPa\n")
        text.append_text(interlock_text(st))
        text.append("\n")
    text.append(f"lab {r.environment or '-'}", style="dim" if not r.environment else "")
    return text


def gate_times(shot: LiveShot | None, config: GateConfig | None) -> dict[int, list[str]]:
    """Each gate's crossings in this shot, as times after the first one (ticks if the tick is unknown)."""
    out: dict[int, list[str]] = {1: [], 2: [], 3: []}
    if shot is None or not shot.crossings:
        return out
    t0 = shot.crossings[0][1]
    for gate, tick in shot.crossings:
        if config is not None:
            delta = (tick - t0) % config.modulus
            out.setdefault(gate, []).append(f"{delta * config.tick_s * 1e3:+8.3f} ms")
        else:
            out.setdefault(gate, []).append(f"+{tick - t0} ticks")
    return out


def gates_panel(r: LiveRun) -> Text:
    """The three gates' latest crossings: in and out, after gate 1's inbound break."""
    times = gate_times(r.shot, r.gate_config)
    text = Text()
    for gate in (1, 2, 3):
        marks = times.get(gate, [])
        text.append(f"G{gate}", style="bold")
        text.append(f" in {marks[0] if marks else '      -   '}")
        text.append(f" out {marks[1] if len(marks) > 1 else '      -   '}")
        if gate < 3:
            text.append("\n")
    return text


def shot_panel(r: LiveRun) -> Text:
    """The live shot: inbound as soon as known, rebound, the metric, valid or why not."""
    s = r.shot
    if s is None:
        return Text("no shot yet", style="dim")
    label, style = SHOT_STATUS[s.status]
    where = f" at {s.location_in:g} in" if s.location_in is not None else ""
    purpose = PURPOSE.get(s.purpose, s.purpose)
    text = Text.assemble((f"shot {s.index}", "bold"), f" {purpose}{where}  ", (label, style), "\n")
    text.append(f"at the gates in {_speed(s.inbound)}  out {_speed(s.rebound)} m/s")
    if s.metric is not None:
        text.append(f"\n{r.metric_name} {s.metric:.4f} ± {s.u or 0.0:.4f}")
    if s.status in ("invalid", "lost"):  # the codes here; the reasons in full on the message line
        codes = [x.split(":")[0] for x in s.reasons] if s.status == "invalid" else ["see below"]
        text.append("\n" + (", ".join(codes) or "no reason given"), style="yellow")
    return text


def _speed(v: float | None) -> str:
    return f"{v:.2f}" if v is not None else "-"


def progress_panel(r: LiveRun) -> Text:
    """The scan, the valid hits, the running average against the limit, the model's prediction."""
    text = Text()
    limit = r.limit or 1.0
    means = r.scan_means()
    scan = [means.get(loc) for loc in r.scan_locations]
    known = [v for v in scan if v is not None]
    text.append("scan  ", style="bold")
    text.append(sparkline(scan, min(known, default=0.0), max(known, default=1.0)), style="cyan")
    if r.scan_locations:
        text.append(f"  {r.scan_locations[0]:g}-{r.scan_locations[-1]:g} in")
    if r.best_location_in is not None:
        text.append(f", best {r.best_location_in:g} in")
    hits = r.hits()
    slots: list[float | None] = [*hits, *[None] * max(r.hits_needed - len(hits), 0)]
    text.append("\nhits  ", style="bold")
    text.append(sparkline(slots, 0.8 * limit, 1.1 * limit), style="cyan")
    text.append(f"  {len(hits)}/{r.hits_needed} valid\n")
    avg = r.average()
    text.append("avg   ", style="bold")
    if avg is None:
        text.append(f"-       limit {limit:g}\n", style="dim")
    else:
        big_u = float(r.verdict.U) if r.verdict and r.verdict.U is not None else 0.0
        text.append(f"{avg:.4f} ")
        text.append_text(gauge(avg, limit, big_u, width=18))
        text.append(f" {limit:g}\n")
    text.append("model ", style="bold")
    if r.prediction is None:
        text.append(r.prediction_note or "-", style="dim")
    else:
        text.append(f"{r.prediction:.4f}  {r.prediction_note}")
    return text


def verdict_text(r: LiveRun) -> Text:
    """The verdict line (empty until the run finishes)."""
    v = r.verdict
    if not v:
        return Text()
    passed = v.verdict == Verdict.PASS
    text = Text(f" {v.verdict} ", style="bold white on green" if passed else "bold white on red")
    if v.mean is not None:
        text.append(
            f" {v.metric} {v.mean:.4f} ± {v.U:.4f} (k={v.coverage_k:g}), limit {v.limit:g}: {v.zone or ''}"
        )
    else:
        text.append(f" {v.reason or ''}")
    return text


# -- the wide layout (120x40 and more): plots, the budget, the device traffic --------------------
def bar(value: float, lo: float, hi: float, width: int, mark: float | None = None) -> Text:
    """A horizontal bar of `value` on [lo, hi] in `width` cells; `mark` (a limit) drawn as │."""
    span = hi - lo if hi > lo else 1.0
    fill = min(max((value - lo) / span, 0.0), 1.0) * width
    at_mark = None if mark is None else min(max(round((mark - lo) / span * width), 0), width - 1)
    text = Text()
    for i in range(width):
        if i == at_mark:
            text.append("│", style="bold red")
        elif i < int(fill):
            text.append("█", style="cyan")
        elif i < fill:
            text.append("▌", style="cyan")
        else:
            text.append("·", style="dim")
    return text


def scan_plot(r: LiveRun, width: int = 16) -> Text:
    """The location scan: one bar per location (mean metric), the chosen one marked."""
    means = r.scan_means()
    locations = sorted(set(r.scan_locations) | set(means))
    known = list(means.values())
    lo, hi = (min(known), max(known)) if known else (0.0, 1.0)
    pad = max((hi - lo) * 0.2, 0.002)
    text = Text()
    for loc in locations:
        v = means.get(loc)
        text.append(f"{loc:>4g} in ")
        if v is None:
            text.append("   -    " + "·" * width, style="dim")
        else:
            text.append(f"{v:.4f} ")
            text.append_text(bar(v, lo - pad, hi + pad, width))
        if loc == r.best_location_in:
            text.append(" best", style="bold")
        text.append("\n")
    text.rstrip()
    return text


def hits_plot(r: LiveRun, width: int = 16) -> Text:
    """The valid hits against the limit (│), then their running average."""
    limit = r.limit or 1.0
    lo, hi = 0.8 * limit, 1.1 * limit
    hits = r.hits()
    text = Text()
    for i in range(max(r.hits_needed, len(hits))):
        text.append(f"hit {i + 1:<2} ")
        if i < len(hits):
            text.append(f"{hits[i]:.4f} ")
            text.append_text(bar(hits[i], lo, hi, width, mark=limit))
        else:
            text.append("   -    " + "·" * width, style="dim")
        text.append("\n")
    avg = r.average()
    text.append("avg    ", style="bold")
    if avg is not None:
        text.append(f"{avg:.4f} ")
        text.append_text(bar(avg, lo, hi, width, mark=limit))
    text.append(f"\nlimit {limit:g}", style="dim")
    return text


def budget_panel(r: LiveRun, rows: int = 8, width: int = 12) -> Text:
    """The last valid shot's uncertainty budget: u, U and the largest shares of the variance."""
    shot = next((s for s in reversed(r.shots.values()) if s.status == "valid"), None)
    outcome = shot.entry.outcome if shot else None
    budget = (outcome.budget if outcome is not None else None) or {}
    out = (budget.get("outputs") or {}).get(r.metric_name) if r.metric_name else None
    if shot is None or not out:
        return Text("no valid shot yet", style="dim")
    text = Text.assemble((f"shot {shot.index} ", "bold"), f"{r.metric_name} {out['value']:.4f}\n")
    text.append(f"u {out['u']:.5f}  U {out['U']:.5f} (k={budget.get('coverage_k', 2):g})\n")
    shares = sorted((out.get("contributions") or {}).items(), key=lambda kv: -kv[1])
    for name, share in [kv for kv in shares if kv[1] > 0][:rows]:
        text.append(f"{name:<9}{share * 100:5.1f} % ")
        text.append_text(bar(share, 0.0, 1.0, width))
        text.append("\n")
    text.rstrip()
    return text


def traffic_panel(r: LiveRun, lines: int = 12) -> Text:
    """The last lines of device traffic ('>' sent to a device, '<' received)."""
    shown = list(r.traffic)[-lines:]
    return Text("\n".join(shown)) if shown else Text("no traffic yet", style="dim")

"""Text renderings of the live run: panels, sparklines and a gauge (no plotting library).

Each function takes the folded state and returns a rich Text that fits a panel about 36
columns wide, so the whole run screen fits an 80x24 terminal.
"""

from __future__ import annotations

from collections.abc import Sequence

from rich.text import Text

from rig.core.devices import CannonState, CannonStatus, GateConfig
from rig.core.events import Verdict
from rig.tui.live import LiveRun, LiveShot

BLOCKS = "▁▂▃▄▅▆▇█"
SHOT_STATUS = {
    "requested": ("firing...", "yellow"),
    "fired": ("measuring...", "yellow"),
    "valid": ("VALID", "bold green"),
    "invalid": ("INVALID", "bold yellow"),
    "lost": ("LOST", "bold red"),
}
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
    if st is None:
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
    text = Text.assemble((f"shot {s.index}", "bold"), f" {s.purpose}{where}  ", (label, style), "\n")
    text.append(f"in  {_speed(s.inbound)}   out {_speed(s.rebound)}")
    if s.metric is not None:
        text.append(f"\n{r.metric_name} {s.metric:.4f} ± {s.u or 0.0:.4f}")
    if s.status in ("invalid", "lost"):  # why, in the lines left
        text.append("\n" + ("; ".join(s.reasons) or "no reason given"), style="yellow")
    return text


def _speed(v: float | None) -> str:
    return f"{v:6.2f} m/s" if v is not None else "     - m/s"


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
        big_u = float(r.verdict["U"]) if r.verdict and "U" in r.verdict else 0.0
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
    passed = v.get("verdict") == Verdict.PASS
    text = Text(f" {v.get('verdict')} ", style="bold white on green" if passed else "bold white on red")
    if "mean" in v:
        text.append(
            f" {v['metric']} {v['mean']:.4f} ± {v['U']:.4f} (k={v['coverage_k']:g}), "
            f"limit {v['limit']:g}: {v.get('zone', '')}"
        )
    else:
        text.append(f" {v.get('reason', '')}")
    return text

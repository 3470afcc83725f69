"""The store's check runs as chart series, acknowledgements of signals, and a rig's chart state.

A series is one rig's check runs on one reference bat (finished runs of kind `check`, oldest
first), each a session of its RunFinished's hits. An acknowledgement is a lab-level, hash-chained
`CheckAcknowledged` entry naming the rig, who, why and the signals it covers (their keys, rule and
session); a signal no acknowledgement names blocks certification on that rig. A run created after
an acknowledgement, before the rig's next check run, ran under it (RigQuality.under).

A restart is a lab-level `CheckRestarted` entry (rig check restart: who, why, the rig and reference
bat) after a corrective action: the series then holds only the check runs created after the latest
restart, whose first sessions are a new phase I; the earlier ones are counted, not charted or judged.
Entries are ordered by when they were first recorded (LogEntry.recorded_utc, the runs' start), so
that a lab's store that rig sync filled orders them as the rig's store did.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

from rig.core import events as ev
from rig.core.outcomes import RunVerdict
from rig.quality import ACK_KIND, CHECK_KIND, RESTART_KIND
from rig.quality.charts import PHASE_I, Charts, Session, Signal, build
from rig.store import RUN_CREATED, LogEntry, Store

Order = tuple[str, int]  # (when first recorded, seq): entries and runs in the order they were made


@dataclass(frozen=True)
class Series:
    """One rig's check sessions on one reference bat, oldest first."""

    rig: str
    bat: str
    metric: str
    sessions: tuple[Session, ...]
    restart: Restart | None = None  # the latest restart: only the sessions after it are here
    earlier: int = 0  # sessions before that restart (not charted)


@dataclass(frozen=True)
class Restart:
    """A recorded new phase I for a rig and reference bat (rig check restart)."""

    seq: int
    rig: str
    bat: str
    who: str
    why: str
    t_utc: str  # when it was first recorded

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view."""
        return {"seq": self.seq, "rig": self.rig, "bat": self.bat, "who": self.who, "why": self.why,
                "t_utc": self.t_utc}  # fmt: skip

    @property
    def order(self) -> Order:
        """Its place among the runs and entries (rig.quality.records.Order)."""
        return self.t_utc, self.seq

    def describe(self) -> str:
        """One line: when, who and why."""
        return f"phase I restarted {self.t_utc} by {self.who}: {self.why}"


@dataclass(frozen=True)
class Ack:
    """A recorded acknowledgement of a rig's signals."""

    seq: int
    rig: str
    who: str
    why: str
    t_utc: str
    keys: tuple[str, ...]
    texts: tuple[str, ...]

    @property
    def order(self) -> Order:
        """Its place among the runs and entries (rig.quality.records.Order)."""
        return self.t_utc, self.seq

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready view (as a run records what it ran under)."""
        return {
            "seq": self.seq,
            "rig": self.rig,
            "who": self.who,
            "why": self.why,
            "t_utc": self.t_utc,
            "signals": list(self.texts),
        }


def _created(store: Store, run_id: str) -> LogEntry | None:
    found = store.entries(run_id, kinds=[RUN_CREATED])
    return found[0] if found else None


def rig_of(created: LogEntry | None) -> str:
    """The rig name a RunCreated recorded ("" for runs from before rigs were named)."""
    meta = created.payload.get("meta") if created else None
    rig = meta.get("rig") if isinstance(meta, dict) else None
    name = rig.get("name") if isinstance(rig, dict) else None
    return name if isinstance(name, str) else ""


def check_series(store: Store) -> tuple[list[Series], dict[str, Order]]:
    """Every (rig, bat) series of finished check runs (after its latest restart), and when each rig's
    latest check run was created (whatever its end: a check started after an acknowledgement
    closes it)."""
    grouped: dict[tuple[str, str], list[tuple[Order, Session]]] = defaultdict(list)
    metrics: dict[tuple[str, str], str] = {}
    latest: dict[str, Order] = {}
    for run in store.runs():
        if run.procedure != CHECK_KIND:
            continue
        created = _created(store, run.run_id)
        rig = rig_of(created)
        made = (run.started_utc, created.seq if created else 0)
        latest[rig] = max(latest.get(rig, made), made)
        if run.status != "finished":
            continue
        for entry in store.entries(run.run_id, kinds=[ev.RUN_FINISHED]):
            verdict = RunVerdict.from_payload(entry.payload, ev.RUN_FINISHED)
            if verdict.hits:
                key = (rig, run.bat_id)
                grouped[key].append((made, Session(run.run_id, tuple(verdict.hits), run.started_utc)))
                metrics.setdefault(key, verdict.metric or "")
    last = {(r.rig, r.bat): r for r in restarts(store)}  # oldest first: the latest wins
    series = []
    for (rig, bat), made_sessions in grouped.items():
        restart = last.get((rig, bat))
        after = [s for made, s in made_sessions if restart is None or made > restart.order]
        earlier = len(made_sessions) - len(after)
        series.append(Series(rig, bat, metrics[(rig, bat)], tuple(after), restart, earlier))
    return series, latest


def restarts(store: Store) -> list[Restart]:
    """The recorded restarts of phase I, oldest first."""
    found = []
    for e in store.entries(None, kinds=[RESTART_KIND]):
        p = e.payload
        if e.run_id is None:
            found.append(
                Restart(e.seq, str(p.get("rig", "")), str(p.get("bat", "")), str(p.get("who", "")),
                        str(p.get("why", "")), e.recorded_utc)
            )  # fmt: skip
    return sorted(found, key=lambda r: r.order)


def restart(store: Store, series: Series, who: str, why: str) -> LogEntry:
    """Record that `who` starts a new phase I for `series`' rig and reference bat, and why."""
    return store.append(None, RESTART_KIND, {"rig": series.rig, "bat": series.bat, "who": who, "why": why})


def acks(store: Store, rig: str | None = None) -> list[Ack]:
    """The recorded acknowledgements (of `rig`, or all), oldest first."""
    found = []
    for e in store.entries(None, kinds=[ACK_KIND]):
        p = e.payload
        if e.run_id is not None or (rig is not None and p.get("rig") != rig):
            continue
        signals = [s for s in p.get("signals") or [] if isinstance(s, dict)]
        found.append(
            Ack(
                e.seq,
                str(p.get("rig", "")),
                str(p.get("who", "")),
                str(p.get("why", "")),
                e.recorded_utc,
                tuple(str(s.get("key", "")) for s in signals),
                tuple(str(s.get("text", "")) for s in signals),
            )
        )
    return sorted(found, key=lambda a: a.order)


@dataclass(frozen=True)
class RigQuality:
    """One rig's charts (by reference bat), its signals not acknowledged, and the acknowledgement a
    run made now would run under (None: none since the rig's last check run)."""

    rig: str
    charts: dict[str, Charts]
    series: dict[str, Series]
    unacknowledged: tuple[tuple[str, Signal], ...]
    acks: tuple[Ack, ...]
    under: Ack | None = None
    notes: tuple[str, ...] = field(default_factory=tuple)

    def refusal(self) -> str | None:
        """Why a new run on this rig is refused (one line), or None."""
        if not self.unacknowledged:
            return None
        bat, first = self.unacknowledged[0]
        more = len(self.unacknowledged) - 1
        also = f" (and {more} more)" if more else ""
        return (
            f"rig {self.rig}: control-chart signal not acknowledged: {first.describe()}, reference bat "
            f"{bat}{also}; see `rig check chart --rig {self.rig}`, then "
            f"`rig check ack --rig {self.rig} --who NAME --why TEXT`"
        )

    def state(self) -> str:
        """The rig's chart state in a few words (the console's first screen)."""
        if not self.charts:
            return "no check runs yet"
        if self.unacknowledged:
            return f"SIGNAL, awaiting acknowledgement ({len(self.unacknowledged)})"
        if not any(c.ready for c in self.charts.values()):
            most = max(c.sessions for c in self.charts.values())
            since = " since the restart" if any(s.restart for s in self.series.values()) else ""
            phase_i = next(iter(self.charts.values())).phase_i
            return f"building phase I ({most} of {phase_i} check runs{since})"
        if self.under is not None:
            return f"signal acknowledged by {self.under.who}; in use until the next check run"
        return "in control"


def rig_quality(store: Store, rig: str, phase_i: int = PHASE_I) -> RigQuality:
    """`rig`'s chart state from the store's check runs and acknowledgements."""
    series, latest = check_series(store)
    mine = {s.bat: s for s in series if s.rig == rig}
    charts = {bat: build(s.sessions, phase_i=phase_i) for bat, s in mine.items()}
    recorded = tuple(acks(store, rig))
    covered = {key for a in recorded for key in a.keys}
    open_signals = tuple(
        (bat, sig) for bat, c in charts.items() for sig in c.signals if sig.key not in covered
    )
    last = recorded[-1] if recorded else None
    under = last if last is not None and last.order > latest.get(rig, ("", 0)) else None
    return RigQuality(rig, charts, mine, open_signals, recorded, under)


def acknowledge(store: Store, quality: RigQuality, who: str, why: str) -> LogEntry:
    """Record that `who` acknowledged every open signal of `quality`'s rig, and why."""
    signals = [{"key": s.key, "bat": bat, "text": s.describe()} for bat, s in quality.unacknowledged]
    payload = {"rig": quality.rig, "who": who, "why": why, "signals": signals}
    return store.append(None, ACK_KIND, payload)

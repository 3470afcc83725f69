"""The run table and the shot table (rig.core.run_phase), once: every phase answers every persisted
kind; real logs, cut anywhere, never meet a refusal, in the fold or in the resumed plan; a plan
that breaks the table is refused before anything is recorded; every output calls an interrupted
run the same; docs/records.md shows the tables as they are."""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.certification import Signoff, certify, end_run, history
from rig.cli import main
from rig.core import events as ev
from rig.core.config import RigConfig
from rig.core.events import RunEvent
from rig.core.run_phase import (
    CLOSED,
    RUN_TABLE,
    SHOT_TABLE,
    RunPhase,
    ShotStatus,
    fold_step,
    markdown,
    refuse,
    shot_refuse,
    shot_step,
    shown,
)
from rig.protocols.control import PlanError
from rig.protocols.dryrun import rehearse
from rig.protocols.plan import Plan, PlanContext, Record
from rig.protocols.procedure import Procedure
from rig.protocols.state import fold
from rig.session import sim_config
from rig.store import Store, shown_status
from tests.cli.test_run_status import _dead_pid
from tests.e2e.test_unopenable_ports import rig_config
from tests.protocols.test_budget import WILD
from tests.protocols.test_executor import BAT, ROOT, FakeRig, executor

FIXTURES = ROOT / "tests" / "fixtures"
PHASES = list(RunPhase)


class Reviewer:
    """Answers yes, except the first shot review it is asked: that shot is overruled."""

    who = "test reviewer"

    def __init__(self) -> None:
        self.reviewed = False

    def ask(self, prompt_id: str, text: str) -> bool:
        if prompt_id.startswith("review-") and not self.reviewed:
            self.reviewed = True
            return False
        return True


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str], dict[str, str]]:
    """A store of runs recorded now, every way the code stops one:
    - `stopped`: a device fault (the faulty scene), resumed into the re-shoot budget (a scattering
      cannon), resumed with a recorded rig check to its verdict, a shot overruled on review;
    - `portless`: created, its devices would not open (interrupted before it started), twice, then run;
    - `unopened`: created, its devices would not open, and left so;
    - `aborted`: stopped by the operator, and left interrupted;
    - `ended`: stopped, then ended without a verdict;
    - `killed`: created, and its runner died without a word (stale lock, nothing recorded).
    Returns the store, the runs' ids and the status each run's last caller was given."""
    folder = tmp_path_factory.mktemp("phases")
    (folder / "wild.toml").write_text(WILD)
    bbcor, ideal = Procedure.load("bbcor"), sim_config("ideal", bat=BAT)
    unopenable = RigConfig.load(rig_config(folder, "/dev/no-such-cannon"))
    ids: dict[str, str] = {}
    said: dict[str, str] = {}
    with Store.open(folder / "r.db") as store:
        faulty = certify(
            store, bbcor, BAT, sim_config("faulty", bat=BAT), operator=Reviewer(), review_shots=True
        )
        assert faulty.status == "interrupted", faulty.reason
        ids["stopped"] = faulty.run_id
        wild = certify(
            store, bbcor, BAT, sim_config(str(folder / "wild.toml"), bat=BAT), run_id=faulty.run_id
        )
        assert wild.budget_exceeded, wild.reason
        check = Signoff("Q. Technician", "cannon serviced")
        done = certify(store, bbcor, BAT, ideal, run_id=faulty.run_id, rig_checked=check)
        said["stopped"] = done.status
        ids["portless"] = store.create_run("bbcor", BAT.id, {})
        for config in (unopenable, unopenable, ideal):
            last = certify(store, bbcor, BAT, config, run_id=ids["portless"])
        said["portless"] = last.status
        ids["unopened"] = store.create_run("bbcor", BAT.id, {})
        said["unopened"] = certify(store, bbcor, BAT, unopenable, run_id=ids["unopened"]).status
        for name in ("aborted", "ended"):
            ids[name], said[name] = _abort_after_the_first_shot(store, bbcor)
        said["ended"] = end_run(store, ids["ended"], Signoff("Q. Manager", "bat withdrawn")).status
        ids["killed"] = store.create_run("bbcor", BAT.id, {})
        held = store.acquire_run(ids["killed"])
    with Store.open(folder / "r.db") as store:  # the runner 'died': its lock names a pid long gone
        store.release_run(held)
        store._conn.execute(
            "INSERT INTO run_locks VALUES (?, 'x', ?, ?, ?, ?, 30)",
            (ids["killed"], held.host, _dead_pid(), held.since_utc, held.heartbeat_utc),
        )
    return folder / "r.db", ids, said


def _abort_after_the_first_shot(store: Store, procedure: Procedure) -> tuple[str, str]:
    """A run the operator stops after its first shot, through the public API; its id and status."""
    import rig.api

    control = rig.api.RunControl()

    def stop(event: Any) -> None:
        if isinstance(event, ev.ShotFired):
            control.abort("lunch break")

    got = rig.api.certify(
        bat=BAT,
        procedure=procedure,
        rig=rig.api.simulated("ideal"),
        store=store,
        on_event=stop,
        control=control,
    )
    assert got.reason == "lunch break" and not got.finished
    return got.run_id, got.status


@pytest.fixture(scope="module")
def logs(recorded: tuple[Path, dict[str, str], dict[str, str]]) -> dict[str, list[RunEvent]]:
    """The recorded runs' logs, and those of the log format 1 fixture (finished, ended, resumed)."""
    v1 = recorded[0].parent / "log-v1.db"  # a copy: opening a store may touch the file
    shutil.copyfile(FIXTURES / "log-v1.db", v1)
    v1_runs: dict[str, str] = json.loads((FIXTURES / "log-v1.runs.json").read_text())
    found: dict[str, list[RunEvent]] = {}
    for db, ids in ((recorded[0], recorded[1]), (v1, v1_runs)):
        with Store.open(db, create=False) as store:
            found |= {f"{db.stem}:{name}": history(store, run_id) for name, run_id in ids.items()}
    return found


# -- the tables ---------------------------------------------------------------------------------
def test_every_phase_answers_every_persisted_kind_and_only_those() -> None:
    assert set(RUN_TABLE) == ev.PERSISTED  # a new persisted kind must be placed in the table
    for kind in ev.PERSISTED:
        for phase in PHASES:
            reason = refuse(kind, phase)
            assert (reason is None) == (phase in RUN_TABLE[kind]), (kind, phase)
            if reason is not None:
                assert kind in reason and str(phase) in reason
            assert fold_step(phase, kind) in PHASES
    for kind in set(ev.BY_KIND) - ev.PERSISTED:  # live only: anywhere, and nothing changes
        assert all(refuse(kind, p) is None and fold_step(p, kind) is p for p in PHASES), kind


def test_only_a_verdict_or_an_end_closes_a_run_and_nothing_follows_either() -> None:
    assert {RunPhase.FINISHED, RunPhase.ENDED} == CLOSED
    closing = {kind for kind, row in RUN_TABLE.items() if set(row.values()) & CLOSED}
    assert closing == {ev.RUN_FINISHED, ev.RUN_ENDED}
    assert {p for kind in (ev.RUN_STARTED, ev.RUN_RESUMED) for p in RUN_TABLE[kind]} == {
        RunPhase.NEW,
        RunPhase.RUNNING,
        RunPhase.INTERRUPTED,
    }
    assert RunPhase.NEW not in RUN_TABLE[ev.RUN_RESUMED] and RunPhase.RUNNING not in RUN_TABLE[ev.RUN_STARTED]


def test_the_shown_status_is_one_of_four_words() -> None:
    words = {(p, alive): shown(p, alive) for p in PHASES for alive in (False, True)}
    assert set(words.values()) == {"running", "interrupted", "finished", "ended"}
    assert words[RunPhase.NEW, True] == words[RunPhase.RUNNING, True] == "running"
    assert words[RunPhase.NEW, False] == words[RunPhase.RUNNING, False] == "interrupted"  # killed
    assert words[RunPhase.INTERRUPTED, True] == "interrupted"  # its runner is on its way out


def test_the_shot_table_follows_a_shot_from_its_request_to_its_end() -> None:
    assert set(SHOT_TABLE) == set(ev.SHOT_KINDS)
    path = [ev.SHOT_REQUESTED, ev.SHOT_FIRED, ev.SHOT_MEASURED, ev.SHOT_OVERRULED]
    status: ShotStatus | None = None
    for kind in path:
        assert shot_refuse(kind, status) is None
        status = shot_step(status, kind)
    assert status == ShotStatus.INVALID
    assert shot_refuse(ev.SHOT_FIRED, ShotStatus.FIRED) is not None  # a shot fires once
    assert shot_refuse(ev.SHOT_MEASURED, ShotStatus.REQUESTED) is not None  # nothing measured unfired
    assert shot_refuse(ev.SHOT_LOST, ShotStatus.VALID) is not None


def test_a_damaged_log_folds_without_an_error() -> None:
    """An old or damaged log is reported, not refused: the fold never raises on the table."""
    verdict = ev.RunFinished(result=ev.RunVerdict(verdict=ev.Verdict.FAIL))
    resumed = ev.RunResumed(shots_so_far=0)
    assert fold([verdict]).phase is RunPhase.FINISHED  # no start recorded: where a verdict leads
    assert fold([resumed]).phase is RunPhase.RUNNING
    after = fold([verdict, resumed, ev.RunEnded(who="x", why="y")])  # nothing reopens a closed run
    assert after.phase is RunPhase.FINISHED and after.finished and after.ended is not None
    shot = fold([ev.ShotEvaluated(index=3, outcome=ev.ShotOutcome(metric=0.5, valid=True))])  # no request
    assert shot.phase is RunPhase.NEW and shot.by_index[3].status == "valid"


# -- real logs ----------------------------------------------------------------------------------
def refusals(events: list[RunEvent]) -> list[tuple[str, str | None, str | None]]:
    """Each persisted event with the run table's and the shot table's refusal of it (None: taken)."""
    phase, out = RunPhase.NEW, []
    shots: dict[int, ShotStatus | None] = {}
    for e in events:
        index = e.data.get("index") if e.kind in SHOT_TABLE else None
        status = shots.get(index) if isinstance(index, int) else None
        out.append(
            (e.kind, refuse(e.kind, phase), shot_refuse(e.kind, status) if index is not None else None)
        )
        phase = fold_step(phase, e.kind)
        if isinstance(index, int):
            shots[index] = shot_step(status, e.kind)
    return out


def test_real_logs_never_meet_a_refusal_and_the_fold_agrees(logs: dict[str, list[RunEvent]]) -> None:
    seen: set[str] = set()
    for name, events in logs.items():
        for kind, run_refusal, shot_refusal in refusals(events):
            assert run_refusal is None and shot_refusal is None, (name, kind, run_refusal, shot_refusal)
            seen.add(kind)
        state = fold(events)
        replay: dict[int, ShotStatus | None] = {}
        for e in events:
            if e.kind in SHOT_TABLE:
                replay[e.data["index"]] = shot_step(replay.get(e.data["index"]), e.kind)
        assert {i: s.status for i, s in state.by_index.items()} == replay, name
    # the logs visit every kind but a scan extension's (the standard scan brackets the sample bat) and
    # the accelerated break-in's (its real log is checked the same way in tests/e2e/test_abi_run.py)
    assert ev.PERSISTED - seen <= {ev.SCAN_EXTENDED, *ev.ABI_KINDS}, ev.PERSISTED - seen


def test_the_fold_ends_where_each_run_stands(logs: dict[str, list[RunEvent]]) -> None:
    phases = {name: fold(events).phase for name, events in logs.items()}
    assert phases["r:stopped"] == phases["r:portless"] == phases["log-v1:finished"] == "finished"
    assert phases["r:aborted"] == "interrupted" and phases["r:ended"] == phases["log-v1:ended"] == "ended"
    assert phases["r:killed"] == "new" and phases["r:unopened"] == "interrupted"
    portless = [e.kind for e in logs["r:portless"]][:3]  # interrupted twice before it started
    assert portless == [ev.RUN_INTERRUPTED, ev.RUN_INTERRUPTED, ev.RUN_STARTED]


@settings(max_examples=25, deadline=None)
@given(cut=st.floats(0.0, 1.0), which=st.sampled_from(["r:stopped", "r:portless", "log-v1:resumed"]))
def test_a_run_cut_anywhere_resumes_without_a_refusal(
    logs: dict[str, list[RunEvent]], cut: float, which: str
) -> None:
    """Any prefix of a real log, as a run killed there leaves it: its fold meets no refusal, and the
    standard plan resumed from it (rehearsed) records nothing the table refuses."""
    events = logs[which]
    prefix = events[: round(cut * len(events))]
    state = fold(prefix)
    rehearsal = rehearse(Procedure.load("bbcor"), BAT, sim_config("ideal", bat=BAT), history=prefix)
    assert not rehearsal.problems, rehearsal.problems
    persisted = [e for e in rehearsal.events if e.persisted]
    assert all(r is None and s is None for _, r, s in refusals(prefix + persisted)), refusals(
        prefix + persisted
    )
    if state.phase not in CLOSED:
        assert persisted and persisted[0].kind in (ev.RUN_STARTED, ev.RUN_RESUMED)


# -- the live run -------------------------------------------------------------------------------
def _records(*events: RunEvent) -> Any:
    def plan(ctx: PlanContext) -> Plan[None]:
        for e in events:
            yield Record(e)

    return plan


@pytest.mark.parametrize(
    ("events", "refused"),
    [
        (
            (ev.RunFinished(result=ev.RunVerdict(verdict=ev.Verdict.PASS)), ev.RunResumed(shots_so_far=0)),
            "no RunResumed in a run that is finished",
        ),
        (
            (ev.RunEnded(who="x", why="y"), ev.LocationSet(from_barrel_end_in=6.0)),
            "no LocationSet in a run that is ended",
        ),
        (
            (ev.RunInterrupted(reason="r"), ev.MoiMeasured(result=ev.MoiResult(moi_kgm2=0.04))),
            "no MoiMeasured in a run that is interrupted",
        ),
        ((ev.RunResumed(shots_so_far=0),), "no RunResumed in a run that is new"),
    ],
)
def test_a_plan_that_breaks_the_table_is_refused_before_it_is_recorded(
    events: tuple[RunEvent, ...], refused: str
) -> None:
    ex, recorded = executor(FakeRig())
    with pytest.raises(PlanError, match=refused):
        ex.run(_records(*events))
    assert [e.kind for e in recorded] == [e.kind for e in events[:-1]]  # the refused one is not recorded


def test_a_second_start_is_refused() -> None:
    started = ev.RunStarted(procedure={}, bat={}, rig={})
    ex, recorded = executor(FakeRig())
    with pytest.raises(PlanError, match="no RunStarted in a run that is running"):
        ex.run(_records(started, started))
    assert [e.kind for e in recorded] == [ev.RUN_STARTED]


# -- one word for an interrupted run --------------------------------------------------------------
def _cli(*argv: str) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        assert main(list(argv)) == 0
    return out.getvalue()


def test_every_output_calls_a_run_the_same(
    recorded: tuple[Path, dict[str, str], dict[str, str]], logs: dict[str, list[RunEvent]]
) -> None:
    """`rig runs` (--json and its table), the report, the console's history word, what the run's
    caller was given (the certification's outcome, the API's result) and the fold's phase (no runner
    holds any of these runs) agree, the interrupted and the killed run included."""
    db, ids, said = recorded
    rows = {r["run_id"]: r for r in json.loads(_cli("runs", "--db", str(db), "--json"))}
    table = _cli("runs", "--db", str(db))
    expected = {"stopped": "finished", "portless": "finished", "aborted": "interrupted"}
    expected |= {"ended": "ended", "killed": "interrupted", "unopened": "interrupted"}
    with Store.open(db) as store:
        for name, run_id in ids.items():
            word = expected[name]
            assert rows[run_id]["status"] == word and rows[run_id]["interrupted"] is (word == "interrupted")
            line = next(line for line in table.splitlines() if run_id[:12] in line)
            assert f" {word} " in line, (name, line)
            assert json.loads(_cli("report", run_id, "--db", str(db), "--format", "json"))["status"] == word
            assert shown_status(store, store.run(run_id)) == word
            assert shown(fold(logs[f"r:{name}"]).phase, runner_alive=False) == word, name
            assert said.get(name, word) == word, name  # the killed run's caller was given nothing


# -- the document -------------------------------------------------------------------------------
def test_the_records_doc_shows_the_tables_as_they_are() -> None:
    doc = (ROOT / "docs" / "records.md").read_text(encoding="utf-8")
    shown_there = re.search(r"<!-- run tables: .*? -->\n\n(.*?)<!-- end of the run tables -->", doc, re.S)
    assert shown_there is not None, "docs/records.md lost its run tables"
    assert shown_there.group(1) == markdown(), "paste rig.core.run_phase.markdown() into docs/records.md"

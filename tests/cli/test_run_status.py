"""One status per run, the same in every output (issue 21, item 6): `rig runs` (table and --json),
`rig report` (JSON, Markdown), the console's history and the outcome all say running, interrupted,
finished or ended; the store keeps its own words (an ended run is stored 'aborted')."""

from __future__ import annotations

import contextlib
import io
import json
import os
from pathlib import Path

import pytest

from rig.certification import Signoff, certify, end_run
from rig.cli import main
from rig.core.bat import BatSpec
from rig.protocols.procedure import Procedure
from rig.protocols.runner import RunControl
from rig.session import sim_config
from rig.store import Store, shown_status
from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE


def _cli(*argv: str) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(list(argv))
    assert code == 0
    return code, out.getvalue()


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str]]:
    """A store with a finished run, an interrupted one, one ended without a verdict, and an open
    run whose runner died without a word (killed: its lock is stale, nothing recorded its end)."""
    folder = tmp_path_factory.mktemp("status")
    (folder / "p.toml").write_text(QUICK_PROCEDURE)
    (folder / "b.toml").write_text(GOOD_BAT)
    procedure, bat = Procedure.load(folder / "p.toml"), BatSpec.load(folder / "b.toml")
    db = folder / "s.db"
    ids: dict[str, str] = {}
    with Store.open(db) as store:
        config = sim_config("ideal", bat=bat)
        ids["finished"] = certify(store, procedure, bat, config).run_id
        for name in ("interrupted", "ended"):
            stop = RunControl()
            stop.abort("stopped for the test")
            outcome = certify(store, procedure, bat, config, control=stop)
            assert outcome.status == "interrupted"
            ids[name] = outcome.run_id
        outcome = end_run(store, ids["ended"], Signoff("Q. Manager", "cannon sent for repair"))
        assert outcome.status == "ended"
        ids["killed"] = store.create_run("bbcor", bat.id, {})
        held = store.acquire_run(ids["killed"])
    with Store.open(db) as store:  # the runner 'died': its lock names a pid that no longer runs
        store.release_run(held)
        store._conn.execute(
            "INSERT INTO run_locks VALUES (?, 'x', ?, ?, ?, ?, 30)",
            (ids["killed"], held.host, _dead_pid(), held.since_utc, held.heartbeat_utc),
        )
    return db, ids


def _dead_pid() -> int:
    pid = os.fork()
    if pid == 0:
        os._exit(0)
    os.waitpid(pid, 0)
    return pid


SHOWN = {"finished": "finished", "interrupted": "interrupted", "ended": "ended", "killed": "interrupted"}


def test_runs_json_and_table_say_the_same(runs: tuple[Path, dict[str, str]]) -> None:
    db, ids = runs
    rows = {r["run_id"]: r for r in json.loads(_cli("runs", "--db", str(db), "--json")[1])}
    for name, run_id in ids.items():
        assert rows[run_id]["status"] == SHOWN[name], name
        assert rows[run_id]["interrupted"] is (SHOWN[name] == "interrupted")
    table = _cli("runs", "--db", str(db))[1]
    for name, run_id in ids.items():
        line = next(line for line in table.splitlines() if run_id[:12] in line)
        assert f" {SHOWN[name]} " in line, line
    assert "aborted" not in table


def test_the_report_and_the_console_say_the_same(runs: tuple[Path, dict[str, str]]) -> None:
    db, ids = runs
    with Store.open(db) as store:
        console = {name: shown_status(store, store.run(run_id)) for name, run_id in ids.items()}
    assert console == SHOWN
    for name, run_id in ids.items():
        record = json.loads(_cli("report", run_id, "--db", str(db), "--format", "json")[1])
        assert record["status"] == SHOWN[name], name
        md = _cli("report", run_id, "--db", str(db), "--format", "md")[1]
        assert f"| record status | {SHOWN[name]} |" in md
        if name == "ended":
            assert (
                "NOT CERTIFIED — run ended without a verdict" in md
                # the banner and the identification; the deviations list its earlier interruption
                and "interrupted" not in md.split("## Deviations")[0]
            )
        elif name != "finished":
            assert "NOT CERTIFIED — run interrupted" in md

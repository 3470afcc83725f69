"""A rig config whose port cannot be opened (issue 21, item 10).

A new run is refused before it is created: one line naming the port, exit 2, nothing recorded
(before, a run was created and at once interrupted, exit 3, and left to be resumed or ended). A
resumed run still records the failure as its interruption: the run exists, and the cable may be
plugged in for the next try.
"""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from rig.store import Store
from tests.balls.test_balls_cli import LOT
from tests.e2e.procs import SAMPLE_BAT
from tests.unit.clirun import Result, run_cli


def _closed_port() -> int:
    """A TCP port on this machine that nothing listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


# an aim table down to ball-test speeds (a CCOR test shoots at 25-35 m/s)
AIM = """
[aim]
pressure_kpa = [20.0, 50.0, 100.0, 200.0, 400.0, 800.0]
speed_m_s = [15.0, 28.0, 37.4, 49.6, 61.3, 68.0]
"""


def rig_config(tmp_path: Path, cannon: str) -> Path:
    """The simulated lab's gates and clamp, with `cannon` as the cannon's port."""
    path = tmp_path / "rig.toml"
    ports = {"cannon": cannon, "gates": "sim://gates?scene=lab", "clamp": "sim://clamp?scene=lab"}
    text = "[ports]\n" + "".join(f'{k} = "{v}"\n' for k, v in ports.items()) + AIM
    path.write_text(text, encoding="utf-8")
    return path


def refused_naming(result: Result, port: str) -> None:
    lines = result.err.strip().splitlines()
    assert result.code == 2 and len(lines) == 1 and "Traceback" not in result.err, result.err
    assert port in lines[0] and "no run was started" in lines[0], lines[0]


@pytest.mark.parametrize("port", ["/dev/no-such-cannon", "socket://127.0.0.1:{free}"])
def test_certify_refuses_before_the_run_naming_the_port(tmp_path: Path, port: str) -> None:
    port = port.format(free=_closed_port())
    db = tmp_path / "r.db"
    config = rig_config(tmp_path, port)
    argv = ["certify", "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--config", str(config)]
    refused_naming(run_cli([*argv, "--db", str(db)], db), port)
    with Store.open(db) as store:
        assert store.runs() == []


def test_a_ball_test_refuses_before_the_run_naming_the_port(tmp_path: Path) -> None:
    (tmp_path / "lot.toml").write_text(LOT, encoding="utf-8")
    db = tmp_path / "b.db"
    assert run_cli(["balls", "register", str(tmp_path / "lot.toml"), "--db", str(db)]).code == 0
    config = rig_config(tmp_path, "/dev/no-such-cannon")
    argv = [
        "balls",
        "test",
        "--procedure",
        "ccor",
        "--lot",
        "ACME-1",
        "--config",
        str(config),
        "--db",
        str(db),
    ]
    refused_naming(run_cli(argv, db), "/dev/no-such-cannon")
    with Store.open(db) as store:
        assert store.runs() == []


def test_a_resumed_run_still_records_the_port_as_its_interruption(tmp_path: Path) -> None:
    db = tmp_path / "r.db"
    first = run_cli(
        ["certify", "--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--sim", "faulty", "--db", str(db)]
    )
    assert first.code == 3, first.err
    run_id = first.err.split("rig certify --resume ")[1].split()[0]
    config = rig_config(tmp_path, "/dev/no-such-cannon")
    again = run_cli(["certify", "--resume", run_id, "--config", str(config), "--db", str(db)], db)
    assert again.code == 3 and "could not be opened" in again.err, again.err
    with Store.open(db) as store:
        last = store.entries(run_id)[-1]
        assert last.kind == "RunInterrupted" and "/dev/no-such-cannon" in last.payload["reason"]

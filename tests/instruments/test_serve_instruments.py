"""`rig sim serve --instruments --write-config` then `rig certify --config`: a bat certified end to
end through the three real-instrument twins (SCPI counter, Modbus PLC, VXM stage) out of process,
with the machine busy; the verdict agrees with today's `--sim lab` within U, the record verifies,
holds each instrument's own traffic, and the certificate lists the instruments."""

from __future__ import annotations

import base64
import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from rig.core import events as ev
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
HARDWARE_CHECKS = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests/hardware"]
SERVE = [
    sys.executable,
    "-m",
    "rig.cli",
    "sim",
    "serve",
    "--scene",
    "lab",
    "--bat",
    str(BAT),
    "--instruments",
]


def _rig(*args: str, timeout: float = 900) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "rig.cli", *args], capture_output=True, text=True, timeout=timeout
    )


def _certified(db: Path, *where: str) -> dict:
    done = _rig("certify", "--procedure", "bbcor", "--bat", str(BAT), *where, "--db", str(db), "--json")
    assert done.returncode in (0, 1), done.stderr[-3000:]
    return json.loads(done.stdout)


@pytest.mark.slow
def test_a_bat_certifies_end_to_end_through_the_three_instrument_twins(
    tmp_path: Path, cpu_load: None
) -> None:
    config = tmp_path / "rig.toml"
    server = subprocess.Popen(
        [*SERVE, "--write-config", str(config)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert server.stdout is not None
        lines = [server.stdout.readline().split() for _ in range(4)]
        assert {line[0]: line[1] for line in lines[:3]} == {
            "cannon": "modbus-cannon",
            "gates": "scpi-counter",
            "clamp": "vxm-stage",
        }, lines
        assert lines[3][:2] == ["rig", "config:"]
        written = tomllib.loads(config.read_text(encoding="utf-8"))
        assert all(table["simulated"] for table in written["devices"].values())
        twins = _certified(tmp_path / "twins.db", "--config", str(config))
        checks = subprocess.run(  # the lab's hardware checks, through whichever drivers the config names
            [*HARDWARE_CHECKS, "--hardware", str(config)],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert checks.returncode == 0 and "4 passed" in checks.stdout, checks.stdout[-3000:]
    finally:
        server.terminate()
        server.wait(timeout=60)
    line = _certified(tmp_path / "line.db", "--sim", "lab")
    a, b = twins["verdict"], line["verdict"]
    assert a["verdict"] == b["verdict"], (a, b)
    assert abs(a["mean"] - b["mean"]) <= max(a["U"], b["U"]), (a["mean"], b["mean"], a["U"])

    verified = _rig("verify", "--db", str(tmp_path / "twins.db"))
    assert verified.returncode == 0, verified.stdout + verified.stderr
    with Store.open(tmp_path / "twins.db") as store:
        (run,) = store.runs()
        entries = store.entries(run.run_id)
    sent: dict[str, bytes] = {"cannon": b"", "gates": b"", "clamp": b""}
    for entry in entries:
        if entry.kind == ev.TRAFFIC:
            for rec in entry.payload.get("chunks", []):
                if rec.get("dir") == "tx":
                    sent[rec["device"]] += base64.b64decode(rec["data_b64"])
    assert b"FETC?" in sent["gates"] and b"INIT" in sent["gates"]  # SCPI text
    assert sent["cannon"] and b"\x00\x00" in sent["cannon"][2:4]  # a Modbus TCP frame (MBAP, protocol 0)
    assert sent["clamp"]  # the stage's ASCII programs
    (identified,) = [e for e in entries if e.kind == ev.INSTRUMENTS_IDENTIFIED]
    makers = {kind: d.get("maker", "") for kind, d in identified.payload["devices"].items()}
    assert all("simulat" in maker.lower() for maker in makers.values()), makers

    report = _rig("report", "last", "--db", str(tmp_path / "twins.db"), "--format", "md")
    assert report.returncode == 0, report.stderr
    section = report.stdout[report.stdout.index("## Instruments") : report.stdout.index("## Lab environment")]
    for driver in ("modbus-cannon", "scpi-counter", "vxm-stage"):
        assert driver in section

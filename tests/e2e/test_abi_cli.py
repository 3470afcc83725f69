"""The accelerated break-in as an operator runs it: `rig certify --procedure abi` from the command line.

A simulated run (--sim composite) is scripted: the rollings the plan asks for roll the simulated
barrel, which is tapped after each. Interrupted by SIGINT mid-way (a real child process) and resumed
with the printed command, the resumed run rolls its new world's barrel as recorded, so that every
compression reading and every stage's BBCOR match the simulated barrel's truth; `rig verify` passes.
A sample bat passes new and fails after two rolling stages. At a terminal (a pty) on a rig served by
instrument twins, a person reports each rolling from prompts, and bad answers are asked again.
"""

from __future__ import annotations

import json
import math
import os
import pty
import select
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from rig.certification import certify
from rig.cli import main
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.errors import ConfigError
from rig.protocols.abi import abi
from rig.protocols.procedure import Procedure
from rig.session import scene_with_bat, sim_config
from rig.sim_break_in import SimBreakIn
from rig.simulators.effects.softening import BarrelSofteningConfig, stiffness_after
from rig.simulators.scene import Scene
from rig.simulators.truth import true_metric
from rig.store import Store
from tests.e2e.procs import ROOT, certify_child, stopped_by_signals

EXAMPLES = ROOT / "protocols" / "examples"
COMPOSITE = EXAMPLES / "composite-bat.toml"
FAILS = EXAMPLES / "composite-bat-fails-after-abi.toml"


@dataclass(frozen=True)
class Stage:
    """One measured stage as recorded, beside the simulated barrel's truth."""

    stage: int
    bbcor: float
    U: float
    verdict: str
    hoop_hz: float | None
    true_hoop_hz: float
    true_bbcor: float
    location_in: float


def _barrel(scene: Scene) -> BarrelSofteningConfig:
    found = [e for e in scene.effects if isinstance(e, BarrelSofteningConfig)]
    assert len(found) == 1
    return found[0]


def replayed(entries: list[dict[str, Any]], bat: Path) -> tuple[list[Stage], list[tuple[float, float]]]:
    """Each stage and each compression reading (read, true force) against the simulated barrel,
    its stiffness replayed from the rollings recorded (rig.simulators.effects.softening)."""
    scene = scene_with_bat(Scene.load("composite"), BatSpec.load(bat))
    barrel = _barrel(scene)
    s, stages, forces = 1.0, [], []
    for e in entries:
        if e["kind"] == ev.BARREL_ROLLED:
            s = stiffness_after(s, float(e["depth_in"]), int(e["passes"]), barrel)
        elif e["kind"] == ev.COMPRESSION_MEASURED:
            forces.append(
                (float(e["force_lbf"]), barrel.stiffness_lbf_per_in * s * float(e["displacement_in"]))
            )
        elif e["kind"] == ev.ABI_STAGE_MEASURED:
            result, hoop = e["result"], scene.bat.hoop_hz * math.sqrt(s)
            softer = scene.model_copy(update={"bat": scene.bat.model_copy(update={"hoop_hz": hoop})})
            location = float(result["location_in"])
            truth = true_metric(softer, (location,)).value
            stages.append(
                Stage(
                    int(e["stage"]),
                    result["mean"],
                    result["U"],
                    result["verdict"],
                    e.get("hoop_hz"),
                    hoop,
                    truth,
                    location,
                )
            )
    return stages, forces


def check_against_truth(stages: list[Stage], forces: list[tuple[float, float]]) -> None:
    """Every compression within 4 SD of the load cell's noise of the true force, every stage's BBCOR
    within its U of the truth, every tapped hoop within 1 % of the true one; the hoop falls and the
    true BBCOR rises from stage to stage."""
    for read, true in forces:
        assert abs(read - true) <= 2.0, (read, true)  # the scene's load cell: SD 0.5 lbf
    for st in stages:
        assert abs(st.bbcor - st.true_bbcor) <= st.U, st
        if st.hoop_hz is not None:
            assert st.hoop_hz == pytest.approx(st.true_hoop_hz, rel=0.01), st
    rolled = [st for st in stages if st.stage > 0]
    for a, b in zip(stages, rolled, strict=False):
        if b.true_hoop_hz < a.true_hoop_hz:  # a stage rolled after the one before
            assert b.true_bbcor > a.true_bbcor


def print_figures(title: str, stages: list[Stage], forces: list[tuple[float, float]]) -> None:
    print(f"\n{title}")
    print("compression (read / true lbf): " + ", ".join(f"{r:.1f}/{t:.1f}" for r, t in forces))
    for st in stages:
        hoop = "-" if st.hoop_hz is None else f"{st.hoop_hz:.0f}"
        print(
            f"stage {st.stage}: hoop {hoop} Hz (true {st.true_hoop_hz:.0f}), BBCOR {st.bbcor:.4f} "
            f"+- {st.U:.4f} (true {st.true_bbcor:.4f}, error {st.bbcor - st.true_bbcor:+.4f}) "
            f"at {st.location_in:g} in: {st.verdict}"
        )


def abi_entries(db: Path, run_id: str) -> tuple[list[dict[str, Any]], list[str]]:
    """The run's ABI entries (as the run record lists them) and all its entry kinds."""
    with Store.open(db) as store:
        entries = store.entries(run_id)
    kinds = [e.kind for e in entries]
    abi_kinds = (*ev.ABI_KINDS, ev.OPERATOR_ANSWERED)
    out = []
    for e in entries:
        if e.kind in ev.ABI_KINDS or (
            e.kind == ev.OPERATOR_ANSWERED and str(e.payload["prompt_id"]).startswith(ev.ABI_DAMAGE_PROMPT)
        ):
            out.append({"kind": e.kind, **e.payload})
    assert all(x["kind"] in abi_kinds for x in out)
    return out, kinds


@pytest.mark.slow
def test_sigint_mid_break_in_then_resume_replays_the_rollings(tmp_path: Path) -> None:
    db = tmp_path / "abi.db"
    child = certify_child(
        db, "--procedure", "abi", "--bat", str(FAILS), "--sim", "composite", "--rolled-by", "A. Roller"
    )
    err = stopped_by_signals(child, db, ev.BARREL_ROLLED, 2)  # stage 1, rolled twice: stop it there
    resume = err.split("resume with: ", 1)[1].splitlines()[0].split()
    assert resume[:3] == ["rig", "certify", "--resume"] and "--bat" in resume and "--sim" in resume, resume
    run_id = resume[3]
    before, kinds = abi_entries(db, run_id)
    assert kinds[-1] == ev.RUN_INTERRUPTED and ev.ABI_STAGE_MEASURED in kinds
    rolled_before = sum(e["kind"] == ev.BARREL_ROLLED for e in before)
    assert rolled_before >= 2
    done = subprocess.run(
        [sys.executable, "-m", "rig.cli", *resume[1:]], cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    assert done.returncode in (0, 1), done.stderr[-3000:]
    assert main(["verify", "--db", str(db)]) == 0
    after, kinds = abi_entries(db, run_id)
    assert after[: len(before)] == before and ev.RUN_RESUMED in kinds and ev.RUN_FINISHED in kinds
    resumed_at = kinds.index(ev.RUN_RESUMED)
    assert ev.ABI_STAGE_MEASURED in kinds[resumed_at:]  # stages measured after the resumption
    stages, forces = replayed(after, FAILS)
    # the first reading after the resumption squeezes the barrel as rolled before it: had the new world's
    # barrel not been rolled again, it would read the new bat's force (check_against_truth's 2 lbf fails)
    print_figures(f"interrupted after {rolled_before} rollings, resumed ({run_id})", stages, forces)
    check_against_truth(stages, forces)
    assert forces[len([e for e in before if e["kind"] == ev.COMPRESSION_MEASURED])][1] < forces[0][1] - 5.0
    assert len({e["stage"] for e in after if e["kind"] == ev.BARREL_ROLLED}) >= 2
    with Store.open(db) as store:
        (entry,) = store.entries(run_id, kinds=[ev.RUN_STARTED])
    assert entry.payload["plan"] == ev.ABI_PLAN


@pytest.mark.slow
def test_the_sample_bat_passes_new_and_fails_after_two_rolling_stages(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "abi.db"
    code = main(
        [
            "certify",
            "--procedure",
            "abi",
            "--bat",
            str(FAILS),
            "--sim",
            "composite",
            "--db",
            str(db),
            "--json",
        ]
    )
    record = json.loads(capsys.readouterr().out)
    assert code == 1  # FAIL
    stages, forces = replayed(record["abi"], FAILS)
    with capsys.disabled():  # the figures, for `pytest -s`
        print_figures("composite-bat-fails-after-abi.toml", stages, forces)
    check_against_truth(stages, forces)
    verdicts = {st.stage: st.verdict for st in stages}
    assert verdicts[0] == "PASS" and verdicts[1] == "PASS" and verdicts[2] == "FAIL", verdicts
    assert [st.stage for st in stages[:3]] == [0, 1, 2]
    rolled = [e for e in record["abi"] if e["kind"] == ev.BARREL_ROLLED]
    assert {e["stage"] for e in rolled} >= {1, 2} and all(e["given"] == ev.BY_SCRIPT for e in rolled)
    assert all(e["who"] == "script" and e["hoop_hz"] is not None for e in rolled)
    assert stages[2].hoop_hz is not None and stages[0].hoop_hz is not None
    assert stages[2].hoop_hz < stages[1].hoop_hz < stages[0].hoop_hz  # tapped: the hoop falls ...
    assert stages[2].true_bbcor > stages[1].true_bbcor > stages[0].true_bbcor  # ... the performance rises
    assert record["verdict"]["verdict"] == "FAIL" and "stage 2 decides" in record["verdict"]["reason"]
    assert main(["report", "last", "--db", str(db)]) == 0
    certificate = capsys.readouterr().out
    assert "Rolling reports: 0 answered at the prompt by a person, 3 given by a script" in certificate
    assert "0.0125 in x 4 (script, script)" in certificate
    assert main(["verify", "--db", str(db)]) == 0


def test_a_scene_whose_barrel_does_not_soften_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "abi.db"
    assert (
        main(["certify", "--procedure", "abi", "--bat", str(COMPOSITE), "--sim", "lab", "--db", str(db)]) == 2
    )
    err = capsys.readouterr().err.strip()
    assert "rolls a barrel that softens: use --sim composite" in err and "\n" not in err
    with Store.open(db) as store:
        assert not store.runs()


def test_a_rig_without_the_barrel_compression_role_is_refused_before_the_run(tmp_path: Path) -> None:
    bat = BatSpec.load(COMPOSITE)
    bench = SimBreakIn()
    try:
        config = bench.attach(sim_config("composite", bat=bat))
        assert any(e.role == "barrel-compression-tester" for e in config.equipment)
        bare = config.model_copy(
            update={"equipment": tuple(e for e in config.equipment if e.role != "barrel-compression-tester")}
        )
        with Store.open(tmp_path / "abi.db") as store:
            with pytest.raises(ConfigError) as caught:
                certify(store, Procedure.load("bbcor"), bat, bare, plan=abi)
            assert not store.runs()  # refused by the rehearsal: no run created
    finally:
        bench.close()
    message = str(caught.value)
    assert "needs the role barrel-compression-tester in the rig's equipment register" in message
    assert "\n" not in message


# -- at a terminal ---------------------------------------------------------------------------------
class Pty:
    """A child on a pseudo-terminal (stdin and stderr; stdout to a file): read until, answer."""

    def __init__(self, argv: list[str], stdout: Path) -> None:
        self.master, slave = pty.openpty()
        self.out = stdout.open("w")
        self.proc = subprocess.Popen(
            argv,
            cwd=ROOT,
            stdin=slave,
            stderr=slave,
            stdout=self.out,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        os.close(slave)
        self.text = ""
        self.seen = 0  # what the last answer answered: a prompt counts only if written after it

    def read_until(self, *endings: str, timeout_s: float = 300.0) -> str:
        """Read until the screen ends with one of `endings` (a prompt waiting); which one."""
        deadline = time.monotonic() + timeout_s
        while True:
            for end in endings:
                if self.text[self.seen :].rstrip(" ").endswith(end.rstrip(" ")):
                    return end
            assert time.monotonic() < deadline, f"no prompt {endings} in {timeout_s} s: {self.text[-2000:]}"
            ready, _, _ = select.select([self.master], [], [], 1.0)
            if ready:
                try:
                    chunk = os.read(self.master, 4096)
                except OSError:  # the child closed the terminal
                    chunk = b""
                if not chunk:  # the terminal closed: the child is ending
                    self.proc.wait(timeout=120)
                    return ""
                self.text += chunk.decode("utf-8", "replace").replace("\r\n", "\n")

    def answer(self, line: str) -> None:
        self.seen = len(self.text)
        os.write(self.master, f"{line}\n".encode())

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        os.close(self.master)
        self.out.close()


INSPECT = "Free of damage? (y/n): "
DEPTH = "Depth rolled, in [0.0125]: "
ANY_DEPTH = "]: "


@pytest.fixture
def served_composite(tmp_path: Path) -> Iterator[Path]:
    """`rig sim serve --scene composite --instruments --write-config`: the rig config of its twins."""
    config = tmp_path / "rig.toml"
    server = subprocess.Popen(
        [
            sys.executable, "-m", "rig.cli", "sim", "serve", "--scene", "composite", "--bat", str(COMPOSITE),
            "--instruments", "--write-config", str(config),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        assert server.stdout is not None
        served = [server.stdout.readline().split() for _ in range(5)]
        assert served[3][:2] == ["compression", "scpi-compression"], served  # the tester is served too
        assert served[4][:2] == ["rig", "config:"]
        yield config
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            server.kill()


def at_terminal(config: Path, db: Path, stdout: Path) -> Pty:
    """`rig certify --procedure abi` on the served rig, at a terminal."""
    return Pty(
        [
            sys.executable, "-m", "rig.cli", "certify", "--procedure", "abi", "--bat", str(COMPOSITE),
            "--config", str(config), "--db", str(db), "--rolled-by", "B. Roller",
        ],
        stdout,
    )  # fmt: skip


@pytest.mark.slow
def test_at_a_terminal_a_person_reports_each_rolling_from_prompts(
    tmp_path: Path, served_composite: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "abi.db"
    term: Pty | None = None
    try:
        term = at_terminal(served_composite, db, tmp_path / "stdout.txt")
        # stage 0's BBCOR, then its inspection: a bad answer, then yes
        assert term.read_until(INSPECT) == INSPECT
        term.answer("maybe")
        assert term.read_until(INSPECT) == INSPECT
        assert "rig: 'maybe': answer y or n; try again\n" in term.text
        term.answer("y")
        # the first rolling: a bad depth, then the default; passes by default; who by default; a hoop
        assert term.read_until(DEPTH) == DEPTH
        assert "Roll the barrel: 4 passes at 0.0125 in depth (stage 1, step 1)" in term.text
        term.answer("0.0125 mm")
        term.read_until(DEPTH)
        assert "rig: '0.0125 mm' is not a depth in inches (e.g. 0.0125); try again" in term.text
        for line in ("", "", "", "1795"):
            term.read_until(ANY_DEPTH, "(blank: not tapped): ")
            term.answer(line)
        # nobody rolls the served barrel: its compression never drops; every later rolling by default
        while got := term.read_until(ANY_DEPTH, "(blank: not tapped): ", INSPECT, timeout_s=300):
            term.answer("y" if got == INSPECT else "")
        code = term.proc.wait(timeout=120)
    finally:
        if term is not None:
            term.close()
    assert code in (0, 1), term.text[-3000:] if term else ""
    with Store.open(db) as store:
        (run,) = store.runs()
        entries = store.entries(run.run_id)
    rolled = [e.payload for e in entries if e.kind == ev.BARREL_ROLLED]
    assert len(rolled) == 12  # protocols/abi.toml's max_steps: the served barrel is never rolled
    assert all(r["given"] == "asked" and r["who"] == "B. Roller" for r in rolled)
    assert (rolled[0]["depth_in"], rolled[0]["passes"], rolled[0]["hoop_hz"]) == (0.0125, 4, 1795.0)
    assert [r["depth_in"] for r in rolled[1:3]] == [0.025, 0.0375] and rolled[1].get("hoop_hz") is None
    inspections = [
        e.payload
        for e in entries
        if e.kind == ev.OPERATOR_ANSWERED and e.payload["prompt_id"].startswith(ev.ABI_DAMAGE_PROMPT)
    ]
    assert inspections and all(i["given"] == "asked" and i["answer"] for i in inspections)
    assert main(["verify", "--db", str(db)]) == 0
    assert main(["report", "last", "--db", str(db)]) == 0
    certificate = capsys.readouterr().out
    assert "Rolling reports: 12 answered at the prompt by a person, 0 given by a script" in certificate
    assert "0.0125 in x 4 (B. Roller, prompt)" in certificate


@pytest.mark.slow
def test_ctrl_c_at_a_prompt_stops_the_run_at_once_resumably(tmp_path: Path, served_composite: Path) -> None:
    db = tmp_path / "abi.db"
    term = at_terminal(served_composite, db, tmp_path / "stdout.txt")
    try:
        assert term.read_until(INSPECT) == INSPECT  # waiting for the person: nothing else to finish
        term.proc.send_signal(signal.SIGINT)
        assert term.read_until("never seen", timeout_s=60) == ""  # the terminal closes: the child ends
        code = term.proc.wait(timeout=60)
    finally:
        term.close()
    assert code == 3, term.text[-2000:]
    assert "interrupted: stopped by SIGINT" in term.text and "resume with: rig certify --resume" in term.text
    with Store.open(db) as store:
        (run,) = store.runs()
        last = store.entries(run.run_id)[-1]
    assert last.kind == ev.RUN_INTERRUPTED and "stopped by SIGINT" in last.payload["reason"]

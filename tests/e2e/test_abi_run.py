"""An accelerated break-in on the simulated lab: a composite bat through two or more rolling stages to a
verdict, interrupted mid-way and resumed, verified; each stage against the simulated barrel's truth."""

from __future__ import annotations

import itertools
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from rig.certification import certify
from rig.cli import main
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import DeviceSpec, RigConfig
from rig.core.errors import ConfigError
from rig.modal.tap import analyze_tap
from rig.modal.wav import read_wav, write_wav
from rig.protocols.abi import abi, stage_results
from rig.protocols.control import ASKED, Answer, Rolling, RunControl
from rig.protocols.procedure import Procedure
from rig.protocols.state import fold
from rig.report.certificate import render
from rig.report.record import run_record
from rig.session import sim_config
from rig.simulators.effects.softening import BarrelSoftening
from rig.simulators.instruments.compression_tester import CompressionTesterTwin
from rig.simulators.truth import true_metric
from rig.simulators.urlhandler import get_world
from rig.simulators.world import SimWorld
from rig.store import Store
from tests.modal.test_tap import FS, ping
from tests.protocols.test_run_phase import refusals

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "composite-bat.toml")


@dataclass
class SimulatedOperator:
    """The lab's operator on the simulated bat: rolls the world's barrel as asked, taps it and measures
    its hoop frequency from the ping (rig.modal.tap), inspects it by its truth; may stop the run."""

    world: SimWorld
    folder: Path
    who: str = "A. Roller"
    stop_after_rolls: int | None = None  # abort the run (as Ctrl-C would) after this many rollings
    control: RunControl | None = None
    rolls: list[tuple[float, int]] = field(default_factory=list)

    @property
    def barrel(self) -> BarrelSoftening:
        assert self.world.barrel is not None
        return self.world.barrel

    def ask(self, prompt_id: str, text: str) -> Answer:
        if prompt_id.startswith(ev.ABI_DAMAGE_PROMPT):
            return Answer(not self.barrel.damaged, ASKED)
        return Answer(True, ASKED)  # ring checks and balls: the simulated rig needs no more

    def roll(self, prompt_id: str, text: str, depth_in: float, passes: int) -> Rolling:
        hoop = self.world.roll(depth_in, passes)
        self.rolls.append((depth_in, passes))
        wav = write_wav(self.folder / f"{prompt_id}.wav", ping(hoop, seed=len(self.rolls)), FS, 16)
        tapped = analyze_tap(read_wav(wav)).hoop
        if self.stop_after_rolls is not None and len(self.rolls) == self.stop_after_rolls:
            assert self.control is not None
            self.control.abort("the lab closes for the night")
        return Rolling(depth_in, passes, self.who, ASKED, tapped.frequency_hz, tapped.u_hz)


@pytest.fixture
def lab() -> Iterator[tuple[RigConfig, SimWorld]]:
    rig = f"abi-{uuid.uuid4().hex[:8]}"
    config = sim_config("composite", rig_name=rig, bat=BAT)
    world = get_world(rig)
    twin = CompressionTesterTwin(world)
    twin.start()
    devices = config.devices.model_copy(update={"compression": DeviceSpec(**twin.device_table())})
    yield config.model_copy(update={"devices": devices}), world
    twin.close()


def test_a_composite_bat_breaks_in_interrupted_and_resumed(
    lab: tuple[RigConfig, SimWorld], tmp_path: Path
) -> None:
    config, world = lab
    procedure = Procedure.load("bbcor")
    control = RunControl()
    first = SimulatedOperator(world, tmp_path, stop_after_rolls=3, control=control)
    db = tmp_path / "abi.db"
    with Store.open(db) as store:
        out = certify(store, procedure, BAT, config, plan=abi, operator=first, control=control)
        assert out.status == "interrupted", out
        second = SimulatedOperator(world, tmp_path)
        second.rolls = list(first.rolls)
        done = certify(store, procedure, BAT, config, plan=abi, operator=second, run_id=out.run_id)
        assert done.status == "finished" and done.run_id == out.run_id
        entries = store.entries(out.run_id)
        assert store.verify().ok
        certificate = render(run_record(store, out.run_id), "md")
    assert main(["verify", "--db", str(db)]) == 0
    events = ev.parse_log(entries)
    state = fold(events)
    assert all(run is None and shot is None for _, run, shot in refusals(events))  # the run tables take it
    kinds = [e.kind for e in entries]
    assert ev.RUN_INTERRUPTED in kinds and ev.RUN_RESUMED in kinds
    identified = [e for e in events if isinstance(e, ev.InstrumentsIdentified)]
    assert len(identified) == 2  # each session's instruments, the compression tester among them
    assert all(e.devices["compression"]["model"] == "BCT-SIM" for e in identified)
    results = stage_results(state)
    rolled_stages = sorted({n.data["stage"] for n in state.abi if n.kind == ev.BARREL_ROLLED})
    assert len(rolled_stages) >= 2, [n.data for n in state.abi]
    # each stage's measured hoop frequency and certified BBCOR against the simulated barrel's truth
    hoops = dict(_stage_hoops(state))
    true_hoops = _true_hoops(world, state)
    assert [s for s, _ in results] == list(hoops) == list(range(len(results)))
    truths = {}
    for (stage, verdict), true_hoop in zip(results, true_hoops, strict=True):
        assert verdict.mean is not None and verdict.U is not None and verdict.location_in is not None
        truths[stage] = _truth(world, true_hoop, verdict.location_in)
        assert abs(verdict.mean - truths[stage]) <= verdict.U, (stage, verdict.mean, truths[stage], verdict.U)
        assert hoops[stage] == pytest.approx(true_hoop, rel=0.01)  # tapped: within 1 %
        assert verdict.cross_check is not None and verdict.cross_check.get("predicted") is not None
    measured = [0, *rolled_stages]
    for a, b in itertools.pairwise(measured):
        assert hoops[b] < hoops[a] and true_hoops[b] < true_hoops[a]  # the hoop falls stage by stage ...
        assert truths[b] > truths[a]  # ... and the barrel's true BBCOR rises
    means = {s: v.mean for s, v in results}
    assert means[measured[-1]] > means[0]  # the certified BBCOR follows it
    assert state.verdict is not None and "after accelerated break-in" in (state.verdict.reason or "")
    # the certificate shows every stage: its compression, rolling, hoop, BBCOR with U, prediction
    section = certificate.split("## Accelerated break-in (NCAA, 2009)", 1)[1].split("\n## ", 1)[0]
    for stage, verdict in results:
        row = next(line for line in section.splitlines() if line.startswith(f"| {stage} |"))
        assert f"{verdict.mean:.4f}" in row and f"{verdict.U:.4f}" in row and f"{hoops[stage]:.0f}" in row
        predicted = (verdict.cross_check or {}).get("predicted")
        assert predicted is not None and f"{predicted:.4f}" in row
    assert f"Verdict after break-in: {state.verdict.verdict}" in section


def _stage_hoops(state: object) -> list[tuple[int, float]]:
    from rig.protocols.state import RunState

    assert isinstance(state, RunState)
    return [
        (int(n.data["stage"]), float(n.data["hoop_hz"])) for n in state.abi if n.kind == ev.ABI_STAGE_MEASURED
    ]


def _true_hoops(world: SimWorld, state: object) -> list[float]:
    """The barrel's true hoop frequency at each measured stage, replayed from the rollings recorded."""
    from rig.protocols.state import RunState
    from rig.simulators.effects.softening import stiffness_after

    assert isinstance(state, RunState) and world.barrel is not None
    s, out = 1.0, []
    for n in state.abi:
        if n.kind == ev.BARREL_ROLLED:
            s = stiffness_after(s, float(n.data["depth_in"]), int(n.data["passes"]), world.barrel.config)
        elif n.kind == ev.ABI_STAGE_MEASURED:
            out.append(world.barrel.new_hoop_hz * s**0.5)
    return out


def _truth(world: SimWorld, hoop_hz: float, location_in: float) -> float:
    """The simulated bat's true BBCOR at `location_in`, with the barrel at `hoop_hz`."""
    scene = world.scene  # its bat is the bat file's (pinned: with_bat would not change it)
    softer = scene.model_copy(update={"bat": scene.bat.model_copy(update={"hoop_hz": hoop_hz})})
    return true_metric(softer, (location_in,)).value


def test_an_operator_who_cannot_report_rolling_stops_the_run_in_one_line(
    lab: tuple[RigConfig, SimWorld], tmp_path: Path
) -> None:
    config, world = lab

    class AnswersOnly:
        who = "console"

        def ask(self, prompt_id: str, text: str) -> Answer:
            return Answer(True, ASKED)

    with Store.open(tmp_path / "abi.db") as store:
        out = certify(store, Procedure.load("bbcor"), BAT, config, plan=abi, operator=AnswersOnly())
        stops = [e for e in store.entries(out.run_id) if e.kind == ev.RUN_INTERRUPTED]
    assert out.status == "interrupted"
    reason = stops[-1].payload["reason"]
    assert "cannot report a rolling step" in reason and "\n" not in reason
    assert world.barrel is not None and world.barrel.stiffness == 1.0  # nobody rolled it


def test_a_rig_without_a_compression_tester_is_refused_before_the_run(
    lab: tuple[RigConfig, SimWorld], tmp_path: Path
) -> None:
    config, world = lab
    bare = config.model_copy(update={"devices": config.devices.model_copy(update={"compression": None})})
    with Store.open(tmp_path / "abi.db") as store:
        with pytest.raises(ConfigError) as caught:
            certify(
                store,
                Procedure.load("bbcor"),
                BAT,
                bare,
                plan=abi,
                operator=SimulatedOperator(world, tmp_path),
            )
        assert not store.runs()  # refused by the rehearsal: no run created
    assert "needs a barrel-compression tester" in str(caught.value) and "\n" not in str(caught.value)


def test_the_dry_run_rehearses_the_break_in(lab: tuple[RigConfig, SimWorld]) -> None:
    from rig.protocols.dryrun import rehearse

    config, _ = lab
    rehearsal = rehearse(Procedure.load("bbcor"), BAT, config, plan=abi)
    assert rehearsal.finished and not rehearsal.problems
    kinds = {e.kind for e in rehearsal.events}
    assert {ev.COMPRESSION_MEASURED, ev.BARREL_ROLLED, ev.ABI_STAGE_MEASURED} <= kinds

"""The console's pure parts: the live fold, the renderings, the key rules, the operator bridge."""

from __future__ import annotations

import contextlib
import threading
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

from rig.certification import certify, history
from rig.core.bat import BatSpec
from rig.core.devices import CannonState, CannonStatus, GateConfig, Interlocks
from rig.protocols.control import ASKED, WITH, Answer
from rig.protocols.procedure import Procedure
from rig.protocols.runner import RunAborted
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store
from rig.tui.live import LiveRun
from rig.tui.operator import CannonRead, ConsoleOperator, GatesRead, PromptClosed, PromptPending
from rig.tui.render import gate_times, gauge, progress_panel, sparkline
from rig.tui.report import record_summary
from rig.tui.situation import Situation, allowed, fire_block, prompt_text, quick_answer
from tests.tui.conftest import QUICK, SAMPLE_BAT


def status(door: bool = True) -> CannonStatus:
    return CannonStatus(CannonState.SAFE, 0.0, 0.0, Interlocks(door, True, True), 0)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """One quick run on the ideal scene, recorded."""
    db = tmp_path_factory.mktemp("parts") / "r.db"
    bat = BatSpec.load(SAMPLE_BAT)
    with Store.open(db) as store:
        out = certify(store, Procedure.load(QUICK), bat, sim_config("ideal", bat=bat))
    return db, out.run_id


def test_the_fold_of_a_recorded_run_matches_its_record(recorded: tuple[Path, str]) -> None:
    db, run_id = recorded
    with Store.open(db) as store:
        events, record = history(store, run_id), run_record(store, run_id)
    live = LiveRun()
    for event in events:
        live.apply(event)
    assert live.hits() == pytest.approx(record["verdict"]["hits"])
    assert live.average() == pytest.approx(record["verdict"]["mean"])
    assert set(live.scan_means()) == {6.5, 7.0} and live.best_location_in == 7.0
    assert live.verdict is not None and live.prediction == pytest.approx(record["cross_check"]["predicted"])
    assert live.shot is not None and len(live.shot.crossings) == 6  # raw ticks of the last shot
    assert "4/2" not in progress_panel(live).plain and "2/2 valid" in progress_panel(live).plain
    summary = record_summary(record)
    assert summary.startswith(f"# Run {run_id[:8]}: finished") and "**PASS**" in summary
    assert summary.count("| valid |\n") == 4  # every shot's status


def test_sparkline_and_gauge() -> None:
    assert sparkline([0.0, 0.5, 1.0, None], 0.0, 1.0) == "▁▅█·"
    assert sparkline([3.0, 3.0], 3.0, 3.0) == "▅▅"  # flat data: mid-height, not a crash
    bar = gauge(0.46, 0.5, 0.01, width=30).plain
    assert len(bar) == 30 and bar.index("│") == 20 and bar.count("█") == 12 and "▒" in bar


def test_gate_times_in_ms_from_the_first_break() -> None:
    shot = SimpleNamespace(crossings=[(1, 2**32 - 10), (2, 40), (3, 90)])  # across a counter wrap
    times = gate_times(shot, GateConfig(3, 100.0, 32))  # type: ignore[arg-type]
    assert times[1] == ["  +0.000 ms"] and times[2] == ["  +0.005 ms"] and times[3] == ["  +0.010 ms"]


def test_fire_is_off_unless_a_fire_prompt_waits_with_every_interlock_closed() -> None:
    fire = PromptPending("fire-3", "Fire shot 3?")
    ready = Situation(running=True, prompt=fire, cannon=status())
    assert fire_block(ready) == ""
    assert fire_block(replace(ready, cannon=status(door=False))) == "interlock open: door"
    assert "paused" in fire_block(replace(ready, paused=True))
    assert "unknown" in fire_block(replace(ready, cannon_error="timeout"))
    ring = PromptPending("ring-before-3", "Ring check?")
    assert fire_block(replace(ready, prompt=ring)) != ""
    assert "Enter/y: passes  n: fails" in prompt_text(replace(ready, prompt=ring)).plain
    assert "FIRE DISABLED" in prompt_text(replace(ready, cannon=status(door=False))).plain
    assert allowed(ready, "fire") is True and allowed(replace(ready, paused=True), "fire") is False
    assert allowed(replace(ready, cannon=status(door=False)), "fire") is None  # shown, but off
    assert allowed(replace(ready, paused=True), "fire_off") is True and not allowed(ready, "fire_off")
    assert allowed(replace(ready, paused=True), "go_on") and not allowed(replace(ready, paused=True), "pause")
    paused = prompt_text(replace(ready, prompt=ring, paused=True)).plain
    assert paused.startswith("PAUSED p goes on") and "Ring check?" in paused  # the pause, then the prompt
    assert allowed(replace(ready, running=False), "fire") is False  # hidden once the run has ended
    assert allowed(replace(ready, running=False, ended="interrupted"), "resume") is True
    assert allowed(replace(ready, running=False, ended="finished"), "resume") is False


def test_operator_waits_for_the_ui_and_polls_the_cannon_meanwhile() -> None:
    seen: list[object] = []
    op = ConsoleOperator(seen.append, poll_s=0.01)
    session = SimpleNamespace(
        cannon=SimpleNamespace(status=status), gates=SimpleNamespace(config=lambda: GateConfig(3, 100.0, 32))
    )
    op.attach(session)  # type: ignore[arg-type]
    answers: list[Answer] = []
    worker = threading.Thread(target=lambda: answers.append(op.ask("ring-before-1", "Ring?")))
    worker.start()
    while op.pending is None:
        pass
    assert not op.answer("fire-1", True)  # not the prompt that waits
    threading.Event().wait(0.05)
    assert op.answer("ring-before-1", False)
    worker.join(2)
    assert answers == [Answer(False, ASKED)]  # answered on its own prompt
    assert isinstance(seen[0], GatesRead) and isinstance(seen[-1], PromptClosed)
    assert sum(isinstance(n, CannonRead) for n in seen) >= 3  # read again while it waited
    op.cancel("aborted by the operator")
    with pytest.raises(RunAborted, match="aborted"):
        op.ask("fire-2", "Fire?")


def test_enter_answers_only_what_needs_no_thought() -> None:
    # by default every inspection is asked on its own prompt: Enter answers the one shown
    assert quick_answer("review-4", ring_check=True) == ()
    assert quick_answer("ring-after-4", ring_check=True) == ()
    # a lab's one key ([console] one_key) also passes the ring checks up to the next hit
    assert quick_answer("review-4", ring_check=True, one_key=True) == ("ring-after-4", "ring-before-5")
    assert quick_answer("ring-after-4", ring_check=True, one_key=True) == ("ring-before-5",)
    assert quick_answer("ring-before-4", ring_check=True, one_key=True) == ()
    assert quick_answer("review-4", ring_check=False, one_key=True) == () and quick_answer("ball", True) == ()
    assert quick_answer("fire-4", ring_check=True, one_key=True) is None  # a fire takes its own key
    assert quick_answer("edge-location", ring_check=True) is None  # a question to think about
    fire = Situation(running=True, prompt=PromptPending("fire-3", "Fire?"), cannon=status())
    assert allowed(fire, "quick") is False and allowed(fire, "answer") is False
    review = replace(fire, prompt=PromptPending("review-3", "Accept?"), ring_check=True)
    assert allowed(review, "quick") is True
    assert prompt_text(review).plain.endswith("Enter/y: accept  n: reject")
    one_key = replace(review, one_key=True)
    assert (
        "Enter: accept, and the ring passes (recorded as given with the acceptance)"
        in prompt_text(one_key).plain
    )


def _ask_in_thread(op: ConsoleOperator, prompt_id: str) -> list[Answer]:
    out: list[Answer] = []

    def ask() -> None:
        with contextlib.suppress(RunAborted):  # the test ends by cancelling the last one
            out.append(op.ask(prompt_id, prompt_id))

    t = threading.Thread(target=ask)
    t.start()
    t.join(0.3)
    return out if not t.is_alive() else []


def test_ring_checks_answered_with_the_key_before_stop_at_anything_else() -> None:
    op = ConsoleOperator(lambda notice: None, poll_s=0.01)
    with pytest.raises(ValueError, match="ring checks"):
        op.answer("review-1", True, ("fire-2",))  # a fire is never answered in advance
    worker = threading.Thread(target=op.ask, args=("review-1", "Accept?"))
    worker.start()
    while op.pending is None:
        pass
    assert op.answer("review-1", True, ("ring-after-1", "ring-before-2"))
    worker.join(2)
    # returned at once: no one was asked, and the answer says which key gave it
    assert _ask_in_thread(op, "ring-after-1") == [Answer(True, WITH, "review-1")]
    assert op.pending is None
    assert _ask_in_thread(op, "edge-location") == []  # something else: it waits for the operator
    assert op.pending is not None and op.pending.prompt_id == "edge-location"
    op.answer("edge-location", True)
    assert _ask_in_thread(op, "ring-before-2") == []  # the carried check did not survive it
    op.cancel("done")

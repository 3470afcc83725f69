"""One way to run: the API, `rig certify`, `rig balls test` and the console rehearse a run once and
give a new run's bat its measured hoop once, through the application layer (rig.certification).

The counts are taken by replacing the functions wherever a loaded module holds them, so a second
call from any layer (an entry point rehearsing on its own, as they once did) is counted too.
"""

from __future__ import annotations

import asyncio
import importlib
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import rig
from rig.cli import main
from rig.modal.link import with_measured_hoop
from rig.protocols.dryrun import rehearse
from rig.tui import ConsoleSettings, RigConsole
from tests.tui.conftest import QUICK, SAMPLE_BAT, answer_prompts, start_run
from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE

ENTRY_POINTS = (
    "rig.api",
    "rig.certification",
    "rig.balls",
    "rig.cli.records",
    "rig.cli.balls",
    "rig.tui.jobs",
)
SMALL_LOT = '[lot]\nid = "L1"\nmaker = "Acme"\nmodel = "NCAA-1"\nballs = 24\n'


def counting(monkeypatch: pytest.MonkeyPatch, func: Callable[..., Any]) -> list[tuple[Any, ...]]:
    """Count the calls of `func` from anywhere: every module attribute bound to it is replaced."""
    for name in ENTRY_POINTS:
        importlib.import_module(name)  # loaded now, so that their own bindings are replaced too
    calls: list[tuple[Any, ...]] = []

    def counted(*args: Any, **kw: Any) -> Any:
        calls.append(args)
        return func(*args, **kw)

    for module in list(sys.modules.values()):
        for attr, value in list(getattr(module, "__dict__", {}).items()):
            if value is func:
                monkeypatch.setattr(module, attr, counted)
    return calls


@pytest.fixture
def counts(monkeypatch: pytest.MonkeyPatch) -> dict[str, list[tuple[Any, ...]]]:
    """The calls of the rehearsal and of the measured-hoop lookup."""
    return {"rehearse": counting(monkeypatch, rehearse), "hoop": counting(monkeypatch, with_measured_hoop)}


def files(tmp_path: Path) -> tuple[str, str]:
    (tmp_path / "proc.toml").write_text(QUICK_PROCEDURE, encoding="utf-8")
    (tmp_path / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    return str(tmp_path / "proc.toml"), str(tmp_path / "bat.toml")


def test_the_api_rehearses_once_new_or_resumed(tmp_path: Path, counts: dict[str, list[Any]]) -> None:
    proc, bat = files(tmp_path)
    control = rig.RunControl()

    def stop_after_the_first_shot(event: Any) -> None:
        if event.kind == "ShotFired":
            control.abort("a break")

    with rig.open_store(tmp_path / "r.db") as store:
        first = rig.certify(
            bat=rig.Bat.load(bat),
            procedure=proc,
            rig=rig.simulated("ideal"),
            store=store,
            on_event=stop_after_the_first_shot,
            control=control,
        )
        assert first.status == "interrupted"
        assert (len(counts["rehearse"]), len(counts["hoop"])) == (1, 1)
        done = rig.certify(rig=rig.simulated("ideal"), store=store, resume=first)
    assert done.finished
    assert (len(counts["rehearse"]), len(counts["hoop"])) == (2, 1)  # a resumed run: no new hoop


def test_rig_certify_rehearses_once(tmp_path: Path, counts: dict[str, list[Any]]) -> None:
    proc, bat = files(tmp_path)
    argv = ["certify", "--procedure", proc, "--bat", bat, "--sim", "ideal", "--db", str(tmp_path / "r.db")]
    assert main([*argv, "--dry-run"]) == 0
    assert (len(counts["rehearse"]), len(counts["hoop"])) == (1, 1)
    assert main(argv) in (0, 1)
    assert (len(counts["rehearse"]), len(counts["hoop"])) == (2, 2)


def test_rig_balls_test_rehearses_once(tmp_path: Path, counts: dict[str, list[Any]]) -> None:
    (tmp_path / "lot.toml").write_text(SMALL_LOT, encoding="utf-8")
    small = (Path(rig.__file__).parent / "protocols" / "ccor.toml").read_text(encoding="utf-8")
    (tmp_path / "ccor.toml").write_text(small.replace("balls_per_speed = 3", "balls_per_speed = 1"))
    db = ["--db", str(tmp_path / "b.db")]
    assert main(["balls", "register", str(tmp_path / "lot.toml"), *db]) == 0
    argv = ["balls", "test", "--procedure", str(tmp_path / "ccor.toml"), "--lot", "L1", "--sim", "ideal", *db]
    assert main(argv) == 0
    assert len(counts["rehearse"]) == 1


def test_the_console_rehearses_once(tmp_path: Path, counts: dict[str, list[Any]]) -> None:
    settings = ConsoleSettings.from_args(
        "ideal", None, tmp_path / "r.db", bat=str(SAMPLE_BAT), procedure=str(QUICK)
    )
    settings.poll_s = 0.25

    async def body() -> None:
        async with RigConsole(settings).run_test(size=(80, 24)) as pilot:
            screen = await start_run(pilot)
            await answer_prompts(pilot, screen)
            assert screen.outcome is not None and screen.outcome.status == "finished"

    asyncio.run(body())
    assert (len(counts["rehearse"]), len(counts["hoop"])) == (1, 1)

"""kill -9 of a certification running through the three instrument twins, then resume: every shot
fired once, at its place, as the simulated world saw it (the twins run in this process, so the
world's own record of each ball launched is the truth the run's record is checked against)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from rig.core.bat import BatSpec
from rig.core.tomlfile import dump_toml
from rig.session import scene_with_bat
from rig.simulators.instruments.serve import rig_config, start_twins
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from rig.store import Store
from tests.e2e.procs import SAMPLE_BAT, certify_child, wait_count

RIG = [sys.executable, "-m", "rig.cli"]
STAGE_STEP_M = 0.00635e-3  # one step of the VXM twin's lead screw


@pytest.mark.slow
@pytest.mark.parametrize("killed_after", [2, 6])
def test_a_run_killed_through_the_twins_resumes_with_every_shot_once_at_its_place(
    tmp_path: Path, cpu_load: None, killed_after: int
) -> None:
    bat = BatSpec.load(SAMPLE_BAT)
    world = SimWorld(scene_with_bat(Scene.load("lab"), bat))
    twins = start_twins(world)
    try:
        config = tmp_path / "rig.toml"
        config.write_text(dump_toml(rig_config(world.scene, twins)), encoding="utf-8")
        db = tmp_path / "r.db"
        where = ("--procedure", "bbcor", "--bat", str(SAMPLE_BAT), "--config", str(config))
        child = certify_child(db, *where)
        try:
            wait_count(db, "ShotFired", killed_after, child, timeout_s=300)
        finally:
            os.kill(child.pid, signal.SIGKILL)
            child.communicate(timeout=60)
        with Store.open(db) as store:
            (run,) = store.open_runs()
        resumed = subprocess.run(
            [*RIG, "certify", "--resume", run.run_id, "--config", str(config), "--db", str(db)],
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert resumed.returncode in (0, 1), resumed.stderr[-3000:]
        truth = list(world.shots)
    finally:
        for twin in twins:
            twin.close()
    with Store.open(db) as store:
        entries = store.entries(run.run_id)
        assert store.verify().ok
    requested = {e.payload["index"]: e.payload for e in entries if e.kind == "ShotRequested"}
    fired = [e.payload["index"] for e in entries if e.kind == "ShotFired"]
    lost = [e.payload["index"] for e in entries if e.kind == "ShotLost"]
    assert all(n == 1 for n in Counter(fired).values())  # no index fired twice
    # every ball the world launched is a recorded firing, or a shot lost to the kill between its
    # FIRE and its record (at most one): nothing fired that the record does not know of
    assert len(fired) <= len(truth) <= len(fired) + min(1, len(lost))
    places = [bat.impact_from_pivot_m(requested[i]["location_in"]) for i in fired]
    launched = [s.impact_from_pivot_m for s in truth]
    matched, at = 0, 0
    for place in places:  # the recorded firings, in order, are the world's launches, in order
        while at < len(launched) and abs(launched[at] - place) > 2 * STAGE_STEP_M + 1e-9:
            at += 1
        assert at < len(launched), f"recorded shot at {place:.5f} m: no launch there (launches {launched})"
        matched, at = matched + 1, at + 1
    assert matched == len(fired)

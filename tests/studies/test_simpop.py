"""`rig-study population --certify N`: a simulated population certified into a store, then studied
(issue 10, 2)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from rig.core.bat import BatSpec
from rig.core.units import INCH
from rig.physics import PivotedBat, predict_bat
from rig.population.store_source import bats_from_store
from rig.simulators.effects.trampoline import TrampolineConfig
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from rig.store import Store
from studies.cli import main
from studies.population.simulated import simulated_bat, simulated_population
from tests.e2e.procs import ROOT, burners, stopped_by_signals

LAB = Scene.load("lab")
TRAMP = next(e for e in LAB.effects if isinstance(e, TrampolineConfig))


def true_bbcor(hoop: float, moi: float, length_in: float, location_in: float, extra: float) -> float:
    """The lab's documented barrel (docs/simulation.md) at a location, solved with rig.physics."""
    assert TRAMP.m2 is not None and TRAMP.c2 is not None
    params = LAB.ball.model_copy(update={"m2": TRAMP.m2, "c2": TRAMP.c2, "k1": LAB.ball.k1 * TRAMP.k1_scale})
    q = (length_in - location_in - 6.0) * INCH
    bat = PivotedBat(moi_kgm2=moi, impact_from_pivot_m=q)
    e_r, e_h = (predict_bat(params, 60.8, h, bat).e_a for h in (None, hoop))
    k = params.m1 * q * q / moi
    w = math.exp(
        -0.5 * ((q - (length_in * INCH - TRAMP.sweet_spot_from_tip_m - 6 * INCH)) / TRAMP.width_m) ** 2
    )
    loss = TRAMP.off_node_loss_bbcor * (1 - w) / (1 + k)  # bending loss off the sweet spot
    return (e_r + w * (e_h + extra / (1 + k) - e_r) - loss) * (1 + k) + k


def test_the_population_is_realistic_and_each_bat_fixed_by_seed_and_index() -> None:
    bats = simulated_population(12, seed=4, altered=3, alteration_bbcor=0.02)
    assert [b.spec for b in bats] == [
        b.spec for b in simulated_population(12, seed=4, altered=3, alteration_bbcor=0.02)
    ]
    assert simulated_population(20, seed=4)[5].spec == simulated_bat(4, 6).spec  # independent of N
    assert len({b.spec.id for b in bats}) == 12
    hoops = [b.spec.hoop_hz for b in bats]
    assert all(1400 <= h <= 3000 for h in hoops) and max(hoops) - min(hoops) > 1200
    for b in bats:
        assert b.spec.length_in in (31, 32, 33, 34) and b.spec.drop == -3
        assert 0.14 < b.moi_kgm2 < 0.24 and b.spec.moi_kgm2 is None  # the rig measures it
    altered = [b for b in bats if b.altered]
    assert len(altered) == 3 and all(
        b.spec.id.startswith("ALT-") and b.alteration_bbcor == 0.02 for b in altered
    )
    for b in altered:  # the altered bat's file carries the unaltered bat's hoop frequency
        assert b.spec.hoop_hz == simulated_bat(4, b.index).spec.hoop_hz
        assert "# ALTERED: +0.02 BBCOR" in b.toml("lab", 4)
    assert not any(b.altered for b in simulated_population(5, seed=4))


def test_certify_a_small_population_into_a_store_that_verifies_and_studies(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "pop.db"
    flags = ["population", "--certify", "3", "--db", str(db), "--seed", "1", "--altered", "1"]
    assert main(flags) == 0
    err = capsys.readouterr().err
    assert "certified 3 bat(s)" in err and "time per certification" in err
    truth = {b.spec.id: b for b in simulated_population(3, seed=1, altered=1)}
    files = {p.stem: BatSpec.load(p) for p in (tmp_path / "pop-bats").glob("*.toml")}
    assert files == {i: b.spec for i, b in truth.items()}
    with Store.open(db) as store:
        assert store.verify().ok
        runs = store.runs()
        assert sorted(r.bat_id for r in runs) == sorted(truth) and all(r.status == "finished" for r in runs)
        finished = {r.bat_id: store.entries(r.run_id, kinds=["RunFinished"])[-1].payload for r in runs}
        rows, notes = bats_from_store(store)
    assert not notes and len(rows) == 3
    for row in rows:
        bat, fin = truth[row.bat_id], finished[row.bat_id]
        assert row.hoop_hz == bat.spec.hoop_hz and row.length_in == bat.spec.length_in
        assert row.moi_kgm2 == pytest.approx(bat.moi_kgm2, rel=0.01)  # measured on the pivot
        assert row.location_in == fin["location_in"] and row.bbcor == pytest.approx(fin["mean"])
        # the scan settles near the sweet spot, inside the procedure's 5.0-7.5 in (it rode to the end
        # of the extension, 8.5 in, before the bending loss off the sweet spot was simulated)
        assert 6.0 <= fin["location_in"] <= 7.5
        tramp = SimWorld(LAB.with_bat(id=row.bat_id)).collision
        expected = true_bbcor(
            bat.spec.hoop_hz,
            bat.moi_kgm2,
            bat.spec.length_in,
            fin["location_in"],
            tramp.offset_bbcor + bat.alteration_bbcor,  # type: ignore[attr-defined]
        )
        # measured within its stated U: the ball's wear, spread and the lab's air are in the budget
        assert abs(row.bbcor - expected) <= fin["U"]
    assert sum(1 for r in rows if r.bat_id.startswith("ALT-")) == 1
    # run again: nothing is certified twice
    assert main(flags) == 0
    assert "certified 0 bat(s)" in capsys.readouterr().err
    with Store.open(db) as store:
        assert len(store.runs()) == 3


def test_a_signal_keeps_the_finished_runs_and_a_rerun_resumes_without_duplicates(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "pop.db"
    flags = ["--certify", "3", "--db", str(db), "--seed", "2"]
    with burners():
        child = subprocess.Popen(
            [sys.executable, "-m", "studies", "population", *flags],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        # stopped once the first bat's run is under way
        err = stopped_by_signals(child, db, "ShotRequested", 3, pause_s=0.05)
    assert "run the same command again" in err
    with Store.open(db) as store:
        before = {r.bat_id: r for r in store.runs()}
        assert store.verify().ok
    interrupted = [r for r in before.values() if r.status == "running"]
    assert len(interrupted) == 1 and len(before) < 3
    assert main(["population", *flags]) == 0
    with Store.open(db) as store:
        after = store.runs()
        assert store.verify().ok
        resumed = store.entries(interrupted[0].run_id, kinds=["RunResumed"])
    assert sorted(r.bat_id for r in after) == sorted(b.spec.id for b in simulated_population(3, seed=2))
    assert all(r.status == "finished" for r in after) and len(after) == 3  # one run per bat
    assert resumed and interrupted[0].run_id in {r.run_id for r in after}


@pytest.mark.parametrize(
    ("flags", "cause"),
    [
        (["--certify", "3"], "--certify needs --db"),
        (["--certify", "3", "--db", "{db}", "--altered", "4"], "--altered 4"),
        (["--certify", "3", "--db", "{db}", "--alteration", "0"], "--alteration 0"),
        (["--certify", "3", "--db", "{db}", "--scene", "no-such-scene"], "no such scene"),
        (["--certify", "3", "--db", "{db}", "--scene", "ideal", "--altered", "1"], "no trampoline effect"),
        (["--certify", "3", "--db", "{db}", "--procedure", "nope"], "no such procedure"),
        (["--data", "x.csv", "--altered", "1"], "go with --certify"),
    ],
)
def test_bad_flags_are_refused_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flags: list[str], cause: str
) -> None:
    db = str(tmp_path / "pop.db")
    assert main(["population", *[f.replace("{db}", db) for f in flags]]) == 2
    err = capsys.readouterr().err
    assert cause in err and "Traceback" not in err
    assert not Path(db).exists() and not (tmp_path / "pop-bats").exists()


def test_other_flags_on_the_same_store_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = str(tmp_path / "pop.db")
    assert main(["population", "--certify", "1", "--db", db, "--seed", "3"]) == 0
    assert main(["population", "--certify", "1", "--db", db, "--seed", "4"]) == 2
    assert "other flags (seed)" in capsys.readouterr().err

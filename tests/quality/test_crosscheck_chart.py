"""The model cross-check's residuals on control charts (ISO/IEC 17025 7.7.1 h), on the simulated lab.

A population certified on the lab calibrates the model; other bats certified with that calibration
on the lab give residuals that stay in control; the same bats certified on a lab whose trampoline is
altered (the contact stiffness scale k1 0.9 -> 0.8: the barrel returns less) drift and signal. The
residuals, limits and EWMA are checked against a calculation written here from the recorded
cross-check's parts. One set of stores for the module (about 15 s).
"""

from __future__ import annotations

import io
import itertools
import json
import math
import shutil
from contextlib import redirect_stdout
from pathlib import Path
from typing import Any

import pytest

from rig.protocols.procedure import BUILTIN_DIR
from rig.quality.charts import ewma_arl, ewma_run_length_quantile
from rig.simulators.scene import SCENES_DIR
from rig.store import Store
from studies.population.simulated import simulated_population
from tests.quality.test_check_lab import REF_BAT
from tests.unit.clirun import QUICK_PROCEDURE, main, run_cli

STEADY = 12  # bats certified with the calibration on the lab as it was calibrated
DRIFTED = 8  # then certified on the lab with its trampoline altered
LAM, K = 0.2, 3.0


def _json(argv: list[str]) -> Any:
    out = io.StringIO()
    with redirect_stdout(out):
        code = main(argv)
    assert code in (0, 1), (argv, code)
    return json.loads(out.getvalue())


def _certify(root: Path, bats: list[Path], scene: str, db: Path) -> list[dict[str, Any]]:
    base = ["certify", "--procedure", str(root / "quick.toml"), "--calibration", str(root / "cal.json")]
    return [_json([*base, "--bat", str(b), "--sim", scene, "--db", str(db), "--json"]) for b in bats]


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    root = tmp_path_factory.mktemp("crosschart")
    (root / "quick.toml").write_text(QUICK_PROCEDURE)
    pop = root / "pop.db"
    certified = ["rig-study", "population", "--certify", "12", "--seed", "4", "--db", str(pop)]
    assert main([*certified, "--procedure", str(root / "quick.toml")]) == 0
    assert main(["model", "calibrate", "--db", str(pop), "--output", str(root / "cal.json")]) == 0
    bats = []
    for bat in simulated_population(STEADY, seed=5):
        path = root / "bats" / f"{bat.spec.id}.toml"
        path.parent.mkdir(exist_ok=True)
        path.write_text(bat.toml("lab", 5))
        bats.append(path)
    altered = root / "altered" / "lab.toml"  # named lab.toml: the same rig, sim-lab
    altered.parent.mkdir()
    text = (SCENES_DIR / "lab.toml").read_text()
    assert "k1_scale = 0.9\n" in text
    altered.write_text(text.replace("k1_scale = 0.9\n", "k1_scale = 0.8\n"))
    steady = root / "steady.db"
    records = _certify(root, bats, "lab", steady)
    drifted = root / "drifted.db"
    shutil.copy(steady, drifted)
    records += _certify(root, bats[:DRIFTED], str(altered), drifted)
    return {"root": root, "steady": steady, "drifted": drifted, "records": records, "bats": bats}


def _series(db: Path, *more: str) -> dict[str, Any]:
    shown = _json(["check", "chart", "--crosscheck", "--db", str(db), "--json", *more])
    assert len(shown["series"]) == 1, shown
    series: dict[str, Any] = shown["series"][0]
    return series


def _by_hand(records: list[dict[str, Any]]) -> tuple[list[float], list[float], list[float]]:
    """z from the recorded parts, the EWMA from 0 and its exact limits (standard values 0 and 1)."""
    zs, ewma, half = [], [], []
    e = 0.0
    for t, record in enumerate(records, start=1):
        cc = record["cross_check"]
        u = math.sqrt(cc["u_model"] ** 2 + cc["u_scatter"] ** 2 + cc["u_measured"] ** 2)
        zs.append((cc["measured"] - cc["predicted"]) / u)
        e = LAM * zs[-1] + (1 - LAM) * e
        ewma.append(e)
        half.append(K * math.sqrt(LAM / (2 - LAM) * (1 - (1 - LAM) ** (2 * t))))
    return zs, ewma, half


def test_steady_residuals_stay_in_control_and_match_a_hand_calculation(lab: dict[str, Any]) -> None:
    records = lab["records"][:STEADY]
    series = _series(lab["steady"])
    assert series["grouped_by"].startswith("the record names no bat model")
    sha = records[0]["cross_check"]["calibration"]["sha256"]
    assert series["calibration_sha256"] == sha and series["series"] == f"calibration {sha[:12]}"
    assert [r["run_id"] for r in series["residuals"]] == [r["run_id"] for r in records]
    zs, ewma, half = _by_hand(records)
    assert [p["mean"] for p in series["points"]] == pytest.approx(zs, rel=1e-9)
    assert [p["ewma"] for p in series["points"]] == pytest.approx(ewma, rel=1e-9, abs=1e-12)
    assert [p["ewma_high"] for p in series["points"]] == pytest.approx(half, rel=1e-12)
    assert [p["ewma_low"] for p in series["points"]] == pytest.approx([-h for h in half], rel=1e-12)
    limits = series["limits"]
    assert (limits["centre"], limits["warning_high"], limits["action_low"]) == (0.0, 2.0, -3.0)
    assert series["phase_i_sessions"] == 0 and all(p["phase"] == 2 for p in series["points"])
    assert series["signals"] == [] and series["blocks_certification"] is False
    mr = sum(abs(b - a) for a, b in itertools.pairwise(zs)) / (len(zs) - 1)
    assert series["observed_sigma"] == pytest.approx(mr / (2 / math.sqrt(math.pi)), rel=1e-9)
    print(f"steady: mean z {sum(zs) / len(zs):+.2f}, own sigma {series['observed_sigma']:.2f}")
    assert 0.4 < series["observed_sigma"] < 1.6  # the calibration's u describes the spread


def test_an_altered_trampoline_signals_within_the_ewma_design(lab: dict[str, Any]) -> None:
    series = _series(lab["drifted"])
    zs = [p["mean"] for p in series["points"]]
    assert len(zs) == STEADY + DRIFTED
    shift = sum(zs[STEADY:]) / DRIFTED  # in sigmas: z's standard value is 1
    arl, q99 = ewma_arl(shift), ewma_run_length_quantile(shift, 0.99)
    signals = series["signals"]
    first = min(s["index"] for s in signals) - STEADY
    print(
        f"altered trampoline: shift {shift:.2f}, predicted ARL {arl:.2f}, 99 % within {q99}; "
        f"signalled at {first} ({', '.join(s['rule'] for s in signals)})"
    )
    assert shift < -1.0 and arl < DRIFTED  # the barrel returns less than the calibration predicts
    assert 1 <= first <= q99
    assert all(s["index"] > STEADY for s in signals)  # the steady runs never signal
    assert all("beyond" in s["text"] and "bat SIM-S5-" in s["text"] for s in signals)


def test_a_signal_is_shown_but_does_not_block_certification(lab: dict[str, Any]) -> None:
    root, db = lab["root"], lab["drifted"]
    shown = run_cli(["check", "chart", "--crosscheck", "--db", str(db)], db)
    assert shown.code == 0
    bat = lab["bats"][-1]
    record = _certify(root, [bat], "lab", db)[0]
    assert record["run_id"] and record["verdict"]["verdict"] in ("PASS", "FAIL")


def test_check_runs_are_never_residuals(lab: dict[str, Any], tmp_path: Path) -> None:
    """A check run whose procedure names the calibration records a calibrated cross-check of the
    reference bat; it is not a certified bat and is left out of the chart."""
    db = tmp_path / "steady.db"
    shutil.copy(lab["steady"], db)
    check = (BUILTIN_DIR / "check.toml").read_text()
    assert "ring_check = false" in check
    proc = tmp_path / "check.toml"
    proc.write_text(
        check.replace("ring_check = false", f'ring_check = false\ncalibration = "{lab["root"] / "cal.json"}"')
    )
    (tmp_path / "ref.toml").write_text(REF_BAT)
    argv = ["check", "--procedure", str(proc), "--bat", str(tmp_path / "ref.toml"), "--hits", "2"]
    _json([*argv, "--sim", "lab", "--db", str(db), "--json"])
    with Store.open(db) as store:
        (run,) = [r for r in store.runs() if r.procedure == "check"]
        (finished,) = store.entries(run.run_id, kinds=["RunFinished"])
    assert finished.payload["cross_check"]["calibrated"] is True  # it would chart, were it read
    assert _series(db) == _series(lab["steady"])


def test_the_plot_and_bad_input(lab: dict[str, Any]) -> None:
    root, db = lab["root"], lab["drifted"]
    assert (
        run_cli(["check", "chart", "--crosscheck", "--db", str(db), "--plot", str(root / "z.png")], db).code
        == 0
    )
    assert (root / "z.png").stat().st_size > 10_000 and (root / "z.svg").exists()
    with Store.open(lab["steady"]) as store:
        assert store.runs()  # the steady store is untouched by the tests that copy it
    for argv, words in (
        (["--model", "calibration 0000"], "no cross-check series 'calibration 0000'"),
        (["--bat", "REF-1"], "--bat names a reference bat"),
    ):
        result = run_cli(["check", "chart", "--crosscheck", "--db", str(db), *argv], db)
        assert result.code == 2 and words in result.err and result.err.count("\n") == 1, result.err
    result = run_cli(["check", "chart", "--db", str(db), "--model", "x"], db)
    assert result.code == 2 and "--model goes with --crosscheck" in result.err


def test_a_bat_model_is_the_maker_and_model_the_run_recorded(lab: dict[str, Any], tmp_path: Path) -> None:
    """Records whose RunStarted bat names a maker and model (bat files that give them) are charted
    per bat model; records that name neither are grouped by the calibration alone."""
    from rig.quality.crosscheck import _model

    db = tmp_path / "steady.db"
    shutil.copy(lab["steady"], db)
    named = tmp_path / "named.toml"
    named.write_text(
        lab["bats"][1].read_text().replace("[bat]\n", '[bat]\nmaker = "Acme"\nmodel = "A1 33/30"\n')
    )
    record = _certify(lab["root"], [named], "lab", db)[0]
    shown = _json(["check", "chart", "--crosscheck", "--db", str(db), "--json"])["series"]
    by_model = {s["bat_model"]: s for s in shown}
    assert set(by_model) == {None, "Acme A1 33/30"}
    acme = by_model["Acme A1 33/30"]
    assert acme["series"].startswith("bat model Acme A1 33/30, calibration ")
    assert [r["run_id"] for r in acme["residuals"]] == [record["run_id"]]
    assert len(by_model[None]["residuals"]) == STEADY

    assert _model({"bat": {"id": "B1", "maker": "Acme", "model": "X-1 33/30"}}) == "Acme X-1 33/30"
    assert _model({"bat": {"id": "B1", "model": "X-1"}}) == "X-1"
    assert _model({"bat": {"id": "B1", "maker": " ", "model": None}}) is None
    assert _model({}) is None

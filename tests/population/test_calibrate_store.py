"""`rig model calibrate --db STORE`: a record store's certified runs as a population source."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from rig.certification import certify
from rig.cli import main
from rig.core.bat import BatSpec
from rig.population import write_population_csv
from rig.population.calfile import load_calibration
from rig.population.store_source import bats_from_store
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.store import Store
from tests.population.test_calibrate import population

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "tests" / "tui" / "quick-bbcor.toml"
STORED = {"ST-1": 2000.0, "ST-2": 2600.0}


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, dict]]:
    """Two bats certified on the ideal simulated rig into one store; their RunFinished payloads."""
    db = tmp_path_factory.mktemp("store") / "records.db"
    finished = {}
    with Store.open(db, create=True) as st:
        for bat_id, hoop in STORED.items():
            bat = BatSpec.model_validate(
                {
                    "id": bat_id,
                    "length_in": 33.0,
                    "weight_oz": 30.0,
                    "barrel": "aluminium",
                    "hoop_hz": hoop,
                    "moi_kgm2": 0.19,
                    "balance_point_in": 22.0,
                }
            )
            out = certify(st, Procedure.load(QUICK), bat, sim_config("ideal", bat=bat))
            (entry,) = st.entries(out.run_id, kinds=["RunFinished"])
            finished[bat_id] = entry.payload
    return db, finished


def test_store_rows_carry_the_certified_u(store: tuple[Path, dict[str, dict]]) -> None:
    db, finished = store
    with Store.open(db) as st:
        rows, notes = bats_from_store(st)
    assert not notes and [r.bat_id for r in rows] == list(STORED)
    for row in rows:
        verdict = finished[row.bat_id]
        assert verdict["metric"] == "bbcor" and verdict["u"] > 0
        assert row.bbcor == pytest.approx(verdict["mean"], rel=1e-12)
        assert row.u_bbcor == pytest.approx(verdict["U"] / verdict["coverage_k"], rel=1e-12)
        assert row.u_besr is None and row.u_bbs is None  # the runs certified BBCOR only
        assert row.hoop_hz == STORED[row.bat_id] and row.location_in == verdict["location_in"]


def test_calibrate_from_a_file_and_a_store(
    store: tuple[Path, dict[str, dict]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db, finished = store
    data = write_population_csv(population(n=10, seed=3), tmp_path / "pop.csv")
    out = tmp_path / "cal.json"
    rc = main(["model", "calibrate", "--data", str(data), "--db", str(db), "--output", str(out), "--json"])
    assert rc == 0
    cal = load_calibration(out)
    assert cal.provenance.n_bats == 12
    by_id = {b["bat_id"]: b for b in cal.bats}
    for bat_id, verdict in finished.items():
        assert by_id[bat_id]["measured"] == pytest.approx(verdict["mean"], rel=1e-12)
        assert by_id[bat_id]["hoop_hz"] == STORED[bat_id]
    # the hash covers the file's bytes and then the store's rows, so a changed store changes it
    with Store.open(db) as st:
        rows, _ = bats_from_store(st)
    blob = (
        data.read_bytes()
        + json.dumps(
            [r.model_dump(mode="json") for r in rows], sort_keys=True, separators=(",", ":")
        ).encode()
    )
    assert cal.provenance.data_sha256 == hashlib.sha256(blob).hexdigest()
    assert str(data) in cal.provenance.data_file and str(db) in cal.provenance.data_file
    capsys.readouterr()


@pytest.mark.parametrize(
    ("how", "cause"),
    [
        ("alone", "too few bats: 2"),
        ("duplicate", "bat id(s) in more than one source: ST-1"),
        ("neither", "give --data POPULATION, --db STORE or both"),
        ("no-store", "absent-records.db: no such store"),
    ],
)
def test_calibrate_store_refusals(
    how: str,
    cause: str,
    store: tuple[Path, dict[str, dict]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    db, _ = store
    argv = ["model", "calibrate", "--output", str(tmp_path / "cal.json")]
    if how == "alone":
        argv += ["--db", str(db)]
    if how == "duplicate":
        rows = population(n=10, seed=3)
        rows[0] = rows[0].model_copy(update={"bat_id": "ST-1"})
        argv += ["--db", str(db), "--data", str(write_population_csv(rows, tmp_path / "p.csv"))]
    if how == "no-store":
        argv += ["--db", str(tmp_path / "absent-records.db")]
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "\n" not in err and cause in err, err
    assert not (tmp_path / "cal.json").exists()
    assert not (tmp_path / "absent-records.db").exists()


REF_BAT = """\
[bat]
id = "REF-CAL-1"
length_in = 33.0
weight_oz = 30.0
barrel = "aluminium"
hoop_hz = 3100.0
balance_point_in = 22.0
moi_kgm2 = 0.19
moi_u_kgm2 = 0.0005
"""


def test_check_runs_are_not_a_population(
    store: tuple[Path, dict[str, dict]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A store with check runs of a reference bat (rig check: the same bat again and again) gives the
    same population rows and the same calibration as the store without them."""
    db, _ = store
    checked = tmp_path / "checked" / db.name  # the same name: a row names its store's file
    checked.parent.mkdir()
    shutil.copy(db, checked)  # the module's store, then check runs on a reference bat (with a hoop)
    ref = tmp_path / "ref.toml"
    ref.write_text(REF_BAT)
    for _ in range(2):
        argv = ["check", "--bat", str(ref), "--sim", "ideal", "--hits", "2", "--db", str(checked), "--json"]
        assert main(argv) == 0
    with Store.open(checked) as st:
        kinds = [r.procedure for r in st.runs()]
        with_checks, notes = bats_from_store(st)
    assert kinds.count("check") == 2 and "REF-CAL-1" in Store.open(checked).bats()
    with Store.open(db) as st:
        without, _ = bats_from_store(st)
    assert [b.model_dump() for b in with_checks] == [b.model_dump() for b in without]
    assert notes == ["bat REF-CAL-1: a check standard (only check runs, rig check): left out"]
    data = write_population_csv(population(n=10, seed=3), tmp_path / "pop.csv")
    records = []
    for source in (db, checked):
        out = tmp_path / f"cal-{len(records)}.json"
        argv = ["model", "calibrate", "--data", str(data), "--db", str(source), "--output", str(out)]
        assert main(argv) == 0
        record = json.loads(out.read_text())
        for volatile in ("created_utc", "data_file"):  # when, and the store's name
            record["provenance"].pop(volatile)
        records.append(record)
    assert records[0] == records[1] and records[0]["provenance"]["n_bats"] == 12
    capsys.readouterr()

"""A bat record links its modal result; rig certify uses the measured hoop frequency in its cross-check."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.cli import main
from rig.core.bat import Barrel, BatSpec
from rig.core.errors import ConfigError
from rig.modal import (
    MODAL_RESULT_KIND,
    ModalResult,
    NoHoopMode,
    SimSettings,
    analyze,
    bat_modes,
    latest_modal_result,
    record_modal_result,
    simulate,
    with_measured_hoop,
    write_csv,
)
from rig.modal.link import sha256_of
from rig.store import Store

BAT_TOML = """[bat]
id = "{id}"
length_in = 33.0
weight_oz = 30.0
barrel = "aluminium"
balance_point_in = 22.0
"""


def bat(hoop: float | None = None, bat_id: str = "AL-1") -> BatSpec:
    return BatSpec(id=bat_id, length_in=33, weight_oz=30, barrel=Barrel.ALUMINIUM, hoop_hz=hoop)


def test_recorded_result_fills_a_bat_without_hoop(
    tmp_path: Path, result: ModalResult, csv_file: Path
) -> None:
    with Store.open(tmp_path / "r.db") as store:
        payload = record_modal_result(store, "AL-1", result, csv_file)
        (entry,) = store.entries(kinds=[MODAL_RESULT_KIND])
        assert entry.run_id is None  # rig-level
        assert entry.payload == payload
        assert payload["sha256"] == sha256_of(csv_file) and len(payload["sha256"]) == 64
        assert payload["hoop_hz"] == result.hoop_hz
        assert payload["bending_hz"] == result.bending_hz
        assert payload["hoop_u_hz"] == result.hoop.u_hz
        filled = with_measured_hoop(store, bat())
        assert filled.hoop_hz == result.hoop_hz
        assert with_measured_hoop(store, bat(hoop=3000.0)).hoop_hz == 3000.0  # the bat file wins
        assert with_measured_hoop(store, bat(bat_id="OTHER")).hoop_hz is None  # another bat's result
        assert store.verify().ok


def test_latest_result_wins(tmp_path: Path, result: ModalResult, csv_file: Path) -> None:
    other = analyze(simulate(SimSettings(hits=2, hit_interval_s=0.15, modes=bat_modes(2500.0))))
    with Store.open(tmp_path / "r.db") as store:
        record_modal_result(store, "AL-1", result, csv_file)
        record_modal_result(store, "AL-1", other, csv_file)
        assert latest_modal_result(store, "AL-1")["hoop_hz"] == other.hoop_hz
        assert with_measured_hoop(store, bat()).hoop_hz == other.hoop_hz


def test_a_bat_registered_before_its_modal_result_is_refused_clearly(
    tmp_path: Path, result: ModalResult, csv_file: Path
) -> None:
    with Store.open(tmp_path / "r.db") as store:
        store.register_bat("AL-1", bat().registered())
        record_modal_result(store, "AL-1", result, csv_file)
        with pytest.raises(ConfigError, match="registered with hoop_hz None before its modal result"):
            with_measured_hoop(store, bat())


def test_no_hoop_mode_cannot_be_linked(tmp_path: Path) -> None:
    modes = tuple(m for m in bat_modes(2000.0) if m.kind == "bending")
    rec = simulate(SimSettings(modes=modes, hits=2, hit_interval_s=0.15))
    path = write_csv(rec, tmp_path / "wood.csv")
    with Store.open(tmp_path / "r.db") as store, pytest.raises(NoHoopMode, match="no hoop mode"):
        record_modal_result(store, "AL-1", analyze(rec), path)


def test_modal_result_reaches_the_certification_cross_check(
    tmp_path: Path, csv_file: Path, result: ModalResult, capsys: pytest.CaptureFixture[str]
) -> None:
    """rig modal analyze --bat --db, then rig certify: the run record's cross-check uses that hoop_hz."""
    bat_file = tmp_path / "bat.toml"
    bat_file.write_text(BAT_TOML.format(id="MODAL-AL-33"))
    db = tmp_path / "r.db"
    assert main(["modal", "analyze", str(csv_file), "--bat", str(bat_file), "--db", str(db), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["linked"]["bat_id"] == "MODAL-AL-33"
    code = main(
        [
            "certify",
            "--procedure",
            "bbcor",
            "--bat",
            str(bat_file),
            "--sim",
            "ideal",
            "--db",
            str(db),
            "--json",
        ]
    )
    record = json.loads(capsys.readouterr().out)
    assert code in (0, 1)
    assert record["cross_check"]["hoop_hz"] == pytest.approx(result.hoop_hz)
    assert record["cross_check"]["predicted"] is not None
    with Store.open(db) as store:
        assert store.bats()["MODAL-AL-33"]["hoop_hz"] == pytest.approx(result.hoop_hz)
    # the population study reads the same store: the bat with its modal frequencies and measured BBCOR
    from studies.cli import main as study

    assert study(["population", "--db", str(db), "--json"]) == 0
    study = json.loads(capsys.readouterr().out)
    (point,) = study["fig5"]
    assert point["hoop_hz"] == pytest.approx(result.hoop_hz)
    assert point["bending_hz"] == pytest.approx(result.bending_hz[0])
    (bbcor_bin,) = study["fig6"]["metrics"]["bbcor"]
    assert bbcor_bin["mean"] == pytest.approx(record["verdict"]["mean"], rel=1e-9)
    assert study["synthetic"] is False
    # and the location the run chose, for the calibration's k = m Q^2 / I
    from rig.population.store_source import bats_from_store

    with Store.open(db) as store:
        (row,), _ = bats_from_store(store)
        (finished,) = [
            e.payload for r in store.runs() for e in store.entries(r.run_id, kinds=["RunFinished"])
        ]
    assert row.location_in == finished["location_in"] and 0 < row.location_in < 36

"""`rig modal analyze|simulate`: JSON shapes, files written, one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.cli import main
from rig.modal import ModalResult


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_analyze_json_shape(csv_file: Path, result: ModalResult, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "modal", "analyze", str(csv_file), "--json")
    assert code == 0
    d = json.loads(out)
    assert d["hoop_hz"] == pytest.approx(result.hoop_hz)
    assert isinstance(d["bending_hz"], list) and len(d["bending_hz"]) == 3
    assert d["hoop_expanded_uncertainty_hz"] == pytest.approx(2 * d["hoop_u_hz"])
    keys = {
        "frequency_hz",
        "damping_ratio",
        "kind",
        "accelerometers",
        "magnitude_ratio",
        "coherence",
        "u_hz",
        "expanded_uncertainty_hz",
        "u_resolution_hz",
        "u_fit_hz",
        "u_spread_hz",
    }
    for mode in d["modes"]:
        assert keys <= mode.keys()
    hoops = [m for m in d["modes"] if m["kind"] == "hoop"]
    assert hoops[0]["frequency_hz"] == d["hoop_hz"] and hoops[0]["accelerometers"] == ["accel1", "accel2"]
    assert d["n_hits"] == 5 and d["resolution_hz"] > 0 and d["settings"]["max_resolution_hz"] == 20.0


def test_analyze_table_and_plot(csv_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = run(capsys, "modal", "analyze", str(csv_file), "--plot", str(tmp_path / "frf.png"))
    assert code == 0
    assert "first hoop frequency: 2100.0" in out and "bending: 175.0" in out
    assert (tmp_path / "frf.png").stat().st_size > 10_000 and (tmp_path / "frf.svg").exists()
    assert "wrote" in err


def test_simulate_then_analyze_uff(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "t.uff"
    code, _, err = run(
        capsys, "modal", "simulate", str(path), "--hoop", "2400", "--hits", "2", "--interval", "0.15"
    )
    assert code == 0 and "hoop 2400 Hz" in err
    code, out, _ = run(capsys, "modal", "analyze", str(path), "--json")
    assert code == 0 and json.loads(out)["hoop_hz"] == pytest.approx(2400.0, abs=0.5)


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (["--double-hit", "2"], "double hit: hit 2"),
        (["--clip-force", "0.7"], "force is clipped"),
    ],
)
def test_bad_recordings_give_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], needle: str
) -> None:
    path = tmp_path / "bad.csv"
    assert run(capsys, "modal", "simulate", str(path), "--hits", "3", "--interval", "0.15", *extra)[0] == 0
    code, out, err = run(capsys, "modal", "analyze", str(path), "--json")
    # with --json the error is also a JSON object on stdout (issue 13, finding 7), the same line
    assert code == 2 and json.loads(out)["error"]["message"] == err.strip().removeprefix("rig: ")
    assert err.startswith("rig: ") and needle in err and err.count("\n") == 1


def test_analyze_refuses_db_without_bat_and_bad_settings(
    csv_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run(capsys, "modal", "analyze", str(csv_file), "--db", "x.db")
    assert code == 2 and "give --bat" in err
    code, _, err = run(capsys, "modal", "analyze", str(csv_file), "--min-coherence", "2")
    assert code == 2 and "min_coherence" in err
    code, _, err = run(capsys, "modal", "analyze", "no-such.csv")
    assert code == 2 and "no such file" in err


def test_band_flags(csv_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(
        capsys, "modal", "analyze", str(csv_file), "--json", "--band-min", "300", "--band-max", "3000"
    )
    d = json.loads(out)
    assert code == 0 and d["band_hz"] == [300.0, 3000.0] and d["settings"]["f_min_hz"] == 300.0
    assert min(d["bending_hz"]) > 300.0  # the 175 Hz bending mode is outside the band asked for
    code, out, err = run(
        capsys, "modal", "analyze", str(csv_file), "--json", "--band-min", "3000", "--band-max", "300"
    )
    assert code == 2 and "f_max_hz" in err and json.loads(out)["error"]["exit_status"] == 2


@pytest.mark.parametrize(
    ("rows", "code", "needle"),
    [
        ([f"{i / 25600:.7g},0,0,0" for i in range(100) if not 40 <= i < 43], "FORMAT", "a gap at sample"),
        ([f"{i / 51200:.4f},0,0,0" for i in range(100)], "FORMAT", "cannot tell the samples apart"),
    ],
)
def test_a_diagnosis_is_one_line_and_a_json_error_with_its_code(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], rows: list[str], code: str, needle: str
) -> None:
    path = tmp_path / "r.csv"
    path.write_text("\n".join(["time_s,force_N,accel1_ms2,accel2_ms2", *rows]) + "\n")
    status, out, err = run(capsys, "modal", "analyze", str(path), "--json")
    assert status == 2 and err.count("\n") == 1 and needle in err
    error = json.loads(out)["error"]
    assert error["code"] == code and error["kind"] == "RecordingFormatError" and needle in error["message"]


def test_a_clipped_recording_through_the_cli(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rig.modal import Recording, SimSettings, bat_modes, simulate, write_csv

    rec = simulate(
        SimSettings(fs=25600.0, hits=3, hit_interval_s=0.2, seed=1, modes=bat_modes(2800.0, 175.0))
    )
    level = 0.6 * float(abs(rec.accel2).max())
    clipped = Recording.build(rec.time_s, rec.force, rec.accel1, rec.accel2.clip(-level, level))
    path = write_csv(clipped, tmp_path / "clipped.csv")
    status, out, err = run(capsys, "modal", "analyze", str(path), "--json")
    assert status == 2 and "accel2 is clipped" in err and json.loads(out)["error"]["code"] == "CLIPPED"


def test_no_bending_mode_reads_as_such(capsys: pytest.CaptureFixture[str]) -> None:
    data = Path(__file__).resolve().parents[1] / "data" / "modal" / "pyfrf_impact_5hits.csv"
    code, out, _ = run(capsys, "modal", "analyze", str(data))
    assert code == 0 and "bending: none found" in out and "none Hz" not in out

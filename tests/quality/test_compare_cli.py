"""`rig compare`: E_n and z per bat against a hand calculation, retests in one store, hostile inputs."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import shutil
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import pytest

from rig.cli import main
from tests.quality.test_scores import reference_algorithm_a

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures"
HEADER = "run_id,rig,bat_id,procedure,status,verdict,mean,expanded_uncertainty,k,started_utc,finished_utc"


def rig(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def summary_csv(path: Path, rows: list[tuple[str, str, float, float]], lab: str) -> Path:
    """A runs_summary export as `rig export` writes it: (bat, procedure, mean, U) per finished run."""
    lines = [HEADER]
    for n, (bat, proc, mean, big_u) in enumerate(rows):
        lines.append(
            f"{lab}{n:030d},{lab},{bat},{proc},finished,PASS,{mean!r},{big_u!r},2.0,"
            f"2026-01-01T00:00:{n:02d}+00:00,2026-01-01T00:01:{n:02d}+00:00"
        )
    path.write_text("\n".join(lines) + "\n")
    return path


# Lab A and lab B measured ten bats (BBCOR); bat B9 reads high in lab A. A bat only one lab tested,
# an unfinished run and another procedure's result are not paired.
A = [
    (f"B{i}", "bbcor", 0.45 + 0.001 * i + (0.02 if i == 9 else 0.0005 * (-1) ** i), 0.010) for i in range(10)
]
B = [(f"B{i}", "bbcor", 0.45 + 0.001 * i, 0.008) for i in range(10)]


@pytest.fixture
def two_labs(tmp_path: Path) -> tuple[Path, Path]:
    a = summary_csv(tmp_path / "a.csv", [*A, ("ONLY-A", "bbcor", 0.46, 0.01), ("B1", "bbs", 42.0, 0.4)], "a")
    b = summary_csv(tmp_path / "b.csv", B, "b")
    with b.open("a") as fh:  # an unfinished run of B3 in lab B: not a result
        fh.write(f"b{'9' * 30},b,B3,bbcor,running,,,,,2026-01-02T00:00:00+00:00,\n")
    return a, b


def test_en_and_z_match_a_hand_calculation(two_labs: tuple[Path, Path]) -> None:
    a, b = two_labs
    code, out, err = rig("compare", "--db", str(a), "--db", str(b), "--sigma-pt", "0.004", "--json")
    assert code == 0, err
    got = json.loads(out)
    assert [p["bat_id"] for p in got["pairs"]] == [f"B{i}" for i in range(10)]
    for p, (_, _, x, u_x), (_, _, ref, u_ref) in zip(got["pairs"], A, B, strict=True):
        assert (p["x"]["mean"], p["x"]["U"], p["X"]["mean"], p["X"]["U"]) == (x, u_x, ref, u_ref)
        en = (x - ref) / math.sqrt(u_x**2 + u_ref**2)  # U_x^2 + U_X^2 = 1.64e-4
        assert p["E_n"] == pytest.approx(en, rel=1e-12)
        assert p["z"] == pytest.approx((x - ref) / 0.004, rel=1e-12)
    b9 = got["pairs"][9]
    # B9: x - X = 0.02: E_n = 0.02 / 0.0128062 = 1.5617 (unsatisfactory), z = 0.02 / 0.004 = 5
    assert b9["E_n"] == pytest.approx(1.5617, abs=1e-4) and b9["E_n_assessment"] == "unsatisfactory"
    assert b9["z"] == pytest.approx(5.0) and b9["z_assessment"] == "unsatisfactory"
    # B1: x - X = -0.0005: E_n = -0.039, z = -0.125
    assert got["pairs"][1]["E_n"] == pytest.approx(-0.0005 / 0.0128062, rel=1e-5)
    assert got["pairs"][1]["z_assessment"] == "satisfactory"
    assert got["sigma_pt"] == {
        "value": 0.004,
        "source": "given",
        "robust_mean_difference": None,
        "bats": None,
    }


def test_sigma_pt_estimated_by_algorithm_a_of_the_differences(two_labs: tuple[Path, Path]) -> None:
    a, b = two_labs
    code, out, _ = rig("compare", "--db", str(a), "--db", str(b), "--json")
    assert code == 0
    got = json.loads(out)
    differences = [x[2] - ref[2] for x, ref in zip(A, B, strict=True)]
    mean, sd = reference_algorithm_a(differences)
    assert got["sigma_pt"]["value"] == pytest.approx(sd, rel=1e-9)
    assert got["sigma_pt"]["robust_mean_difference"] == pytest.approx(mean, rel=1e-9, abs=1e-15)
    assert got["sigma_pt"]["source"] == "algorithm A" and got["sigma_pt"]["bats"] == 10
    for p, d in zip(got["pairs"], differences, strict=True):
        assert p["z"] == pytest.approx(d / sd, rel=1e-9)
    assert got["pairs"][9]["z_assessment"] == "unsatisfactory"


def test_the_table_names_both_sources_and_how_sigma_was_found(two_labs: tuple[Path, Path]) -> None:
    a, b = two_labs
    code, out, _ = rig("compare", "--db", str(a), "--db", str(b))
    assert code == 0
    assert f"{a} (x) against {b} (X)" in out
    assert "Algorithm A's robust SD of 10 differences" in out
    assert "unsatisfactory" in out and "+1.56" in out


def test_too_few_bats_for_a_robust_sigma_leave_z_out_with_one_line(tmp_path: Path) -> None:
    a = summary_csv(tmp_path / "a.csv", A[:3], "a")
    b = summary_csv(tmp_path / "b.csv", B[:3], "b")
    code, out, _ = rig("compare", "--db", str(a), "--db", str(b), "--json")
    got = json.loads(out)
    assert code == 0 and [p["z"] for p in got["pairs"]] == [None] * 3
    assert got["notes"] == ["no z: a robust sigma_pt needs at least 8: give --sigma-pt (3 bats paired)"]


def _fixture_store(tmp_path: Path) -> Path:
    copy = tmp_path / "records.db"
    shutil.copyfile(FIXTURES / "log-8802354.db", copy)  # opening may touch it: never the committed file
    return copy


def test_retests_in_one_store_against_a_hand_calculation(tmp_path: Path) -> None:
    with (FIXTURES / "log-8802354.runs_summary.csv").open() as fh:
        rows = [r for r in csv.DictReader(fh) if r["bat_id"] == "SAMPLE-AL-33" and r["procedure"] == "bbcor"]
    first, again = (r for r in rows if r["mean"])  # the third run ended without a result
    x, u_x, ref, u_ref = (
        float(v)
        for v in (again["mean"], again["expanded_uncertainty"], first["mean"], first["expanded_uncertainty"])
    )
    code, out, err = rig("compare", "--db", str(_fixture_store(tmp_path)), "--json")
    assert code == 0, err
    got = json.loads(out)
    assert got["mode"] == "retests" and len(got["pairs"]) == 1
    pair = got["pairs"][0]
    assert (pair["x"]["run_id"], pair["X"]["run_id"]) == (again["run_id"], first["run_id"])
    # 0.46383 - 0.45367 = 0.010163; sqrt(0.0084424^2 + 0.0109071^2) = 0.013793: E_n = 0.7369
    assert pair["E_n"] == pytest.approx((x - ref) / math.hypot(u_x, u_ref), rel=1e-12)
    assert pair["E_n"] == pytest.approx(0.7369, abs=1e-4) and pair["E_n_assessment"] == "satisfactory"
    assert pair["z"] is None


def test_a_store_against_its_own_exports(tmp_path: Path) -> None:
    db = _fixture_store(tmp_path)
    for fmt in ("csv", "parquet"):
        out_file = tmp_path / f"summary.{fmt}"
        assert (
            rig(
                "export",
                "--db",
                str(db),
                "--view",
                "runs_summary",
                "--format",
                fmt,
                "--output",
                str(out_file),
            )[0]
            == 0
        )
        code, out, err = rig("compare", "--db", str(db), "--db", str(out_file), "--json")
        assert code == 0, err
        pairs = json.loads(out)["pairs"]
        assert {(p["bat_id"], p["procedure"]) for p in pairs} == {
            ("SAMPLE-AL-33", "bbcor"),
            ("SAMPLE-AL-33", "besr"),
            ("SAMPLE-AL-33", "bbs"),
        }
        assert all(p["E_n"] == 0.0 and p["x"] == p["X"] for p in pairs)


def _nested_parquet(path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    nested = {name: [{"a": 1}] for name in HEADER.split(",")}
    pq.write_table(pa.table(nested), path)


HOSTILE = [
    ("binary.csv", lambda p: p.write_bytes(bytes(range(256)) * 4), "NUL bytes"),
    ("latin1.csv", lambda p: p.write_bytes(HEADER.encode() + b"\n\xe9\n"), "not UTF-8 text"),
    ("other.csv", lambda p: p.write_text("name,value\nx,1\n"), "no column run_id, bat_id, procedure"),
    ("shots.json", lambda p: p.write_text('{"runs": [[[[1]]]]}'), "no column"),
    ("short.csv", lambda p: p.write_text(HEADER + "\na,b,c\n"), "line 2 has 3 cells, the header 11"),
    (
        "word.csv",
        lambda p: p.write_text(HEADER + "\nr,rig,B1,bbcor,finished,PASS,lots,0.01,2,t,t\n"),
        "line 2: mean 'lots' is not a number",
    ),
    ("nested.parquet", _nested_parquet, "column run_id holds struct"),
    ("cut.parquet", lambda p: p.write_bytes(b"PAR1" + b"\x01" * 100), "unreadable Parquet"),
    ("fake.db", lambda p: p.write_bytes(b"SQLite format 3\x00" + b"\x00" * 200), ""),
    ("missing.csv", lambda p: None, "no such file"),
    ("folder", lambda p: p.mkdir(), "a directory"),
]


@pytest.mark.parametrize(("name", "make", "needle"), HOSTILE, ids=[h[0] for h in HOSTILE])
def test_a_hostile_or_foreign_file_gets_one_line(tmp_path: Path, name: str, make, needle: str) -> None:
    good = summary_csv(tmp_path / "good.csv", B, "b")
    bad = tmp_path / name
    make(bad)
    code, out, err = rig("compare", "--db", str(bad), "--db", str(good))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith(f"rig: {bad}") and needle in err, err


def test_an_endless_fifo_reads_as_an_empty_file(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    code, _, err = rig("compare", "--db", str(fifo))
    assert code == 2 and err.count("\n") == 1 and "no column" in err


def test_three_sources_are_refused(tmp_path: Path) -> None:
    good = str(summary_csv(tmp_path / "good.csv", B, "b"))
    code, _, err = rig("compare", "--db", good, "--db", good, "--db", good)
    assert code == 2 and "give one --db (its retests) or two (A against B), not 3" in err


@pytest.mark.parametrize("sigma", ["0", "-1", "nan", "inf"])
def test_a_bad_sigma_pt_is_refused(tmp_path: Path, sigma: str) -> None:
    good = str(summary_csv(tmp_path / "good.csv", B, "b"))
    code, _, err = rig("compare", "--db", good, "--db", good, f"--sigma-pt={sigma}")
    assert code == 2 and "--sigma-pt" in err and err.count("\n") == 1

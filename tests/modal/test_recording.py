"""Reading recordings: the CSV format and its refusals, UFF (dataset 58) through pyuff."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig.modal import (
    CSV_HEADER,
    Recording,
    RecordingFormatError,
    analyze,
    read_csv,
    read_recording,
    write_csv,
)
from rig.modal.uff import read_uff, write_uff

GOOD_ROWS = [f"{i / 1000:.3f},{0.0},{0.0},{0.0}" for i in range(20)]


def write(tmp_path: Path, text: str, name: str = "r.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_csv_round_trip_keeps_every_sample(recording: Recording, csv_file: Path) -> None:
    back = read_csv(csv_file)
    assert back.n == recording.n
    assert back.fs == pytest.approx(recording.fs, rel=1e-9)
    for name in ("force", "accel1", "accel2"):
        np.testing.assert_allclose(back.channel(name), recording.channel(name), rtol=1e-7, atol=1e-6)
    assert csv_file.read_text().splitlines()[1] == CSV_HEADER  # after the comment line


@pytest.mark.parametrize(
    ("header", "needle"),
    [
        ("time,force_N,accel1_ms2,accel2_ms2", "missing time_s; unexpected time"),
        ("time_s,force_N,accel1_ms2", "missing accel2_ms2"),
        ("time_s,force_N,accel1_ms2,accel2_ms2,accel3_ms2", "unexpected accel3_ms2"),
        ("time_s,force_N,accel2_ms2,accel1_ms2", "columns out of order"),
        ("time_s,force_N,accel1_g,accel2_ms2", "missing accel1_ms2; unexpected accel1_g"),
    ],
)
def test_csv_header_must_be_exact(tmp_path: Path, header: str, needle: str) -> None:
    path = write(tmp_path, "\n".join([header, *GOOD_ROWS]))
    with pytest.raises(RecordingFormatError, match="must be exactly") as err:
        read_csv(path)
    assert needle in str(err.value)
    assert "line 1" in str(err.value)


@pytest.mark.parametrize(
    ("row", "needle"),
    [
        ("0.0205,1.0,oops,0.0", "line 23: accel1_ms2 'oops' is not a number"),
        ("0.0205,1.0,0.0", "line 23: 3 values, expected 4"),
        ("0.0205,1.0,0.0,0.0,9", "line 23: 5 values, expected 4"),
        ("0.0205,nan,0.0,0.0", "force_N is nan at sample 23"),
        ("0.0205,1.0,inf,0.0", "accel1_ms2 is inf at sample 23"),
    ],
)
def test_csv_bad_rows_are_named(tmp_path: Path, row: str, needle: str) -> None:
    path = write(tmp_path, "\n".join(["# comment", CSV_HEADER, *GOOD_ROWS, row]))
    with pytest.raises(RecordingFormatError) as err:
        read_csv(path)
    assert needle in str(err.value)


def test_csv_time_must_increase_evenly(tmp_path: Path) -> None:
    rows = list(GOOD_ROWS)
    rows[5] = "0.003,0,0,0"  # back in time
    with pytest.raises(RecordingFormatError, match="not strictly increasing at sample 7"):
        read_csv(write(tmp_path, "\n".join([CSV_HEADER, *rows])))
    rows = list(GOOD_ROWS)
    rows[5] = "0.0055,0,0,0"  # a late sample: uneven sampling
    with pytest.raises(RecordingFormatError, match="sampling is not even"):
        read_csv(write(tmp_path, "\n".join([CSV_HEADER, *rows])))


def test_csv_empty_short_and_missing_files(tmp_path: Path) -> None:
    with pytest.raises(RecordingFormatError, match="empty"):
        read_csv(write(tmp_path, "# only a comment\n"))
    with pytest.raises(RecordingFormatError, match="no samples after the header"):
        read_csv(write(tmp_path, CSV_HEADER + "\n"))
    with pytest.raises(RecordingFormatError, match="at least 16"):
        read_csv(write(tmp_path, "\n".join([CSV_HEADER, *GOOD_ROWS[:5]])))
    with pytest.raises(RecordingFormatError, match="no such file"):
        read_recording(tmp_path / "absent.csv")


def test_uff_round_trip_and_same_hoop(recording: Recording, tmp_path: Path) -> None:
    path = write_uff(recording, tmp_path / "rec.uff")
    back = read_recording(path)
    assert back.n == recording.n
    assert back.fs == pytest.approx(recording.fs, rel=1e-5)  # UFF keeps 6 digits of the step
    for name in ("force", "accel1", "accel2"):
        np.testing.assert_allclose(back.channel(name), recording.channel(name), rtol=1e-9, atol=1e-9)
    assert analyze(back).hoop_hz == pytest.approx(analyze(recording).hoop_hz, abs=0.05)


def _uff_sets(rec: Recording, **changes: dict) -> list[dict]:
    import pyuff

    base = {
        "binary": 0,
        "func_type": 1,
        "rsp_node": 1,
        "ref_node": 1,
        "ref_dir": 3,
        "abscissa_spacing": 1,
        "abscissa_spec_data_type": 17,
        "orddenom_spec_data_type": 0,
        "z_axis_spec_data_type": 0,
        "x": rec.time_s,
    }
    chans = {
        "force": {"rsp_dir": 3, "ordinate_spec_data_type": 4, "data": rec.force},
        "a1": {"rsp_dir": 3, "ordinate_spec_data_type": 12, "data": rec.accel1},
        "a2": {"rsp_dir": 1, "ordinate_spec_data_type": 12, "data": rec.accel2},
    }
    for key, extra in changes.items():
        chans[key] = {**chans[key], **extra}
    return [pyuff.prepare_58(**base, id1=k, **v) for k, v in chans.items()]


def test_uff_accelerometer_1_is_the_one_in_line_with_the_hammer(recording: Recording, tmp_path: Path) -> None:
    import pyuff

    sets = _uff_sets(recording)
    path = tmp_path / "swapped.uff"
    pyuff.UFF(str(path)).write_sets([sets[0], sets[2], sets[1]], mode="overwrite")  # accel 2 first in file
    back = read_uff(path)
    np.testing.assert_allclose(back.accel1, recording.accel1, rtol=1e-9, atol=1e-9)


def test_uff_g_units_are_converted(recording: Recording, tmp_path: Path) -> None:
    import pyuff

    sets = _uff_sets(recording, a2={"data": recording.accel2 / 9.80665, "ordinate_axis_units_lab": "g"})
    path = tmp_path / "g.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    np.testing.assert_allclose(read_uff(path).accel2, recording.accel2, rtol=1e-9, atol=1e-9)


def test_uff_needs_one_force_and_two_accelerations(recording: Recording, tmp_path: Path) -> None:
    import pyuff

    sets = _uff_sets(recording, a2={"ordinate_spec_data_type": 8})  # a displacement, not an acceleration
    path = tmp_path / "bad.uff"
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    with pytest.raises(RecordingFormatError, match="found 1 and 1"):
        read_uff(path)
    (tmp_path / "junk.uff").write_text("not a universal file\n")
    with pytest.raises(RecordingFormatError, match=r"junk\.uff"):
        read_recording(tmp_path / "junk.uff")


def test_write_csv_then_analyze_gives_the_same_result(recording: Recording, tmp_path: Path) -> None:
    path = write_csv(recording, tmp_path / "x.csv")
    assert analyze(read_csv(path)).hoop_hz == pytest.approx(analyze(recording).hoop_hz, abs=1e-3)


def test_time_written_in_milliseconds_is_named_not_analysed(recording: Recording, tmp_path: Path) -> None:
    """Issue 13, finding 1: a time column in ms under the name time_s was read as a 25.6 Hz record."""
    good = write_csv(recording, tmp_path / "s.csv")
    lines = good.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("time_s,"))
    rows = [line.split(",") for line in lines[at + 1 :]]
    as_ms = [",".join([repr(float(r[0]) * 1000.0), *r[1:]]) for r in rows]
    mislabelled = write(tmp_path, "\n".join([lines[at], *as_ms]) + "\n", "ms.csv")
    with pytest.raises(RecordingFormatError, match=r"too slow for an impact test.*milliseconds.*time_ms"):
        read_csv(mislabelled)
    named = write(tmp_path, "\n".join([lines[at].replace("time_s,", "time_ms,"), *as_ms]) + "\n", "named.csv")
    again = read_csv(named)  # the unit named in the header is honoured
    assert again.fs == pytest.approx(recording.fs, rel=1e-6)
    assert analyze(again).hoop_hz == pytest.approx(analyze(recording).hoop_hz, abs=1e-3)


def _rewrite_time(recording: Recording, tmp_path: Path, name: str, fmt: object) -> Path:
    """The good recording with its time column re-exported by `fmt` (a callable on each time)."""
    good = write_csv(recording, tmp_path / f"{name}-src.csv")
    lines = good.read_text().splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("time_s,"))
    rows = [line.split(",", 1) for line in lines[at + 1 :]]
    body = [f"{fmt(float(t))},{rest}" for t, rest in rows]  # type: ignore[operator]
    return write(tmp_path, "\n".join([lines[at], *body]) + "\n", f"{name}.csv")


@pytest.mark.parametrize(
    ("name", "fmt"),
    [
        ("seven-digits", lambda t: f"{t:.7g}"),  # a spreadsheet's export: 7 significant digits
        ("float32", lambda t: repr(float(np.float32(t)))),  # a float32 time column, printed in full
        ("six-decimals", lambda t: f"{t:.6f}"),  # a fixed number of decimals (1 us, 5 % of a step)
    ],
)
def test_time_rounded_by_an_export_is_read_at_its_true_rate(
    recording: Recording, tmp_path: Path, name: str, fmt: object
) -> None:
    """Issue 13, finding 2: rounded time was refused as 'gaps or a changed sample rate'."""
    rounded = read_csv(_rewrite_time(recording, tmp_path, name, fmt))
    # the rate from a least-squares line through the rounded times: within the rounding / record length
    assert rounded.fs == pytest.approx(recording.fs, rel=2e-6)
    assert analyze(rounded).hoop_hz == pytest.approx(analyze(recording).hoop_hz, abs=1e-3)


def test_time_too_coarse_to_tell_samples_apart_is_named(recording: Recording, tmp_path: Path) -> None:
    coarse = _rewrite_time(recording, tmp_path, "coarse", lambda t: f"{t:.4f}")  # 0.1 ms > the 20 us step
    with pytest.raises(RecordingFormatError, match=r"printed to 0\.0001 s.*cannot tell the samples apart"):
        read_csv(coarse)


def test_a_real_gap_and_a_rate_change_are_told_apart(tmp_path: Path) -> None:
    t = np.arange(400) / 25600.0
    rows = [f"{x:.7g},0,0,0" for x in t]
    gap = rows[:150] + rows[153:]  # three samples lost
    with pytest.raises(RecordingFormatError, match=r"gap at sample 152: 3 samples missing") as err:
        read_csv(write(tmp_path, "\n".join([CSV_HEADER, *gap]), "gap.csv"))
    assert "changed" not in str(err.value)
    t2 = np.concatenate([t[:200], t[199] + np.arange(1, 201) / 12800.0])
    changed = [f"{x:.7g},0,0,0" for x in t2]
    with pytest.raises(
        RecordingFormatError, match=r"sample rate changes at sample 202 from 25600 Hz to 12800 Hz"
    ):
        read_csv(write(tmp_path, "\n".join([CSV_HEADER, *changed]), "rate.csv"))


def test_a_time_column_that_wanders_is_refused_saying_how_far(recording: Recording) -> None:
    """A logger that adds a float32 step to a float32 clock: every step is within its rounding, but
    the rounding is biased and the clock wanders steps away from an even axis (a rate error of
    about 1e-4, 0.2 Hz at 2 kHz): refused, naming how far, not read at a wrong rate."""
    t = np.cumsum(np.full(recording.n, np.float32(recording.dt), dtype=np.float32), dtype=np.float32)
    t -= t[0]
    with pytest.raises(
        RecordingFormatError, match=r"wanders off an even axis .* by up to .* steps, at sample"
    ):
        Recording.build(t, recording.force, recording.accel1, recording.accel2)


def test_comment_and_blank_lines_inside_the_data(recording: Recording, tmp_path: Path) -> None:
    """Review of issue 13: '# pause' inside the data ended in a traceback; after blank lines the
    sample numbers in messages were off by their count. Comment and blank lines are skipped, and a
    message names the file's own line."""
    good = write_csv(recording, tmp_path / "g.csv").read_text().splitlines()
    at = next(i for i, line in enumerate(good) if line.startswith("time_s,"))
    lines = [*good[: at + 1000], "# pause", "", *good[at + 1000 :]]
    back = read_csv(write(tmp_path, "\n".join(lines) + "\n", "c.csv"))
    assert back.n == recording.n and back.fs == pytest.approx(recording.fs, rel=1e-9)
    broken = list(lines)
    nan_at = at + 3000  # 0-based index into `broken`: file line nan_at + 1
    broken[nan_at] = broken[nan_at].replace(broken[nan_at].split(",")[1], "nan", 1)
    with pytest.raises(RecordingFormatError, match=rf"force_N is nan at sample {nan_at + 1} "):
        read_csv(write(tmp_path, "\n".join(broken) + "\n", "n.csv"))


@pytest.mark.parametrize(
    ("name", "shift", "fmt"),
    [
        ("negative start, 7 digits", -0.2, lambda t: f"{t:.7g}"),
        ("negative start, 7 digits, 0.5 s", -0.5, lambda t: f"{t:.7g}"),
        ("Unix time, 7 decimals", 1732430000.0, lambda t: f"{t:.7f}"),
    ],
)
def test_time_around_zero_or_far_from_it(
    recording: Recording, tmp_path: Path, name: str, shift: float, fmt: object
) -> None:
    """Review of issue 13: a pre-trigger time starting below zero, printed to 7 significant digits,
    was refused as uneven (the first steps, rounded more finely near zero, set the reference); Unix
    time with 7 decimals too (a float64's own spacing there is 2.4e-7 s)."""
    path = _rewrite_time(
        recording, tmp_path, name.replace(" ", "-").replace(",", ""), lambda t: fmt(t + shift)
    )  # type: ignore[operator]
    back = read_csv(path)
    assert back.fs == pytest.approx(recording.fs, rel=2e-6)


@pytest.mark.parametrize(
    ("header", "needle"),
    [
        ("time_s;force_N;accel1_ms2;accel2_ms2", "separated by semicolons: the separator must be ','"),
        ("time_s\tforce_N\taccel1_ms2\taccel2_ms2", "separated by tabs: the separator must be ','"),
        ("time_s,force_N,accel1_ms2,accel2_ms2,", "(a trailing comma)"),
    ],
)
def test_a_foreign_separator_is_named(tmp_path: Path, header: str, needle: str) -> None:
    """Review of issue 13: these said 'missing time_s, force_N, ...; unexpected time_s;force_N;...'."""
    with pytest.raises(RecordingFormatError) as err:
        read_csv(write(tmp_path, "\n".join([header, *GOOD_ROWS])))
    assert needle in str(err.value)

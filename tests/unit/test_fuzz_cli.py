"""Extreme values through every file type and every numeric flag of the CLI (Hypothesis).

Each example runs `rig` in-process on the simulated rig with a fresh record store, and asserts
what the developers' guide promises for bad input: exit 0, 1, 2 or 3, never a traceback, and
never a run left 'running' without its interruption recorded (and the resume command printed).
"""

from __future__ import annotations

import copy
import csv
import io
import tempfile
import tomllib
from functools import cache
from pathlib import Path
from typing import Any

from hypothesis import given, settings
from hypothesis import strategies as st

from rig.core.config import RigConfig
from rig.protocols.procedure import Procedure
from rig.simulators.scene import Scene
from tests.unit.clirun import GOOD_BAT, QUICK_PROCEDURE, ROOT, Result, run_cli, toml_document

# 0, negative, denormal-small, huge, huge ints, NaN/inf (as floats and as strings), wrong types
EXTREMES: list[Any] = [
    0,
    -1,
    0.0,
    -0.0,
    1e-300,
    -1e-300,
    5e-324,
    1e300,
    -1e300,
    1.7976931348623157e308,
    2**63 - 1,
    -(2**63),
    10**40,
    float("nan"),
    float("inf"),
    float("-inf"),
    "nan",
    "inf",
    "-1e300",
    "",
    "yes",
    "\x00\xff",
    True,
    False,
    [],
    [1e300, 1e300, 1e300],
    {},
]
FLAG_EXTREMES = [str(v) for v in EXTREMES if not isinstance(v, list | dict)] + ["0x10", "1_000", "1e", "-"]

# The profile's examples for each file type and for the flags: most are refused in milliseconds,
# the few valid ones run a two-location certification, so the module stays near 30 s in CI.
EXAMPLES = settings().max_examples


def check(result: Result) -> None:
    """The promise for any input."""
    assert result.code in (0, 1, 2, 3), (result.code, result.err)
    assert "Traceback" not in result.err, result.err
    assert result.stray_runs == [], result.err
    if result.code == 3:
        assert "rig certify --resume" in result.err, result.err


def leaves(data: Any, path: tuple = ()) -> list[tuple]:
    """Every path to a value inside nested dicts and lists (containers included)."""
    out = [path] if path else []
    if isinstance(data, dict):
        for k, v in data.items():
            out += leaves(v, (*path, k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out += leaves(v, (*path, i))
    return out


def _set(data: Any, path: tuple, value: Any, drop: bool) -> None:
    *head, last = path
    for key in head:
        data = data[key]
    if drop:
        del data[last]
    else:
        data[last] = value


@st.composite
def mutated(draw: st.DrawFn, base: dict, table: str | None = None, keep: tuple[str, ...] = ()) -> bytes:
    """A TOML file: `base` with one value made extreme (or dropped), or binary garbage."""
    how = draw(st.sampled_from(["value", "value", "value", "value", "drop", "garbage"]))
    if how == "garbage":
        return draw(st.binary(max_size=300))
    data = copy.deepcopy(base)
    # every field equally likely, however long its list: pick the field, then an element of it
    fields: dict[tuple, list[tuple]] = {}
    for p in leaves(data):
        if p[0] in keep:
            continue
        fields.setdefault(tuple(k for k in p if isinstance(k, str)), []).append(p)
    path = draw(st.sampled_from(fields[draw(st.sampled_from(sorted(fields)))]))
    _set(data, path, draw(st.sampled_from(EXTREMES)), how == "drop")
    return toml_document(data, table).encode("utf-8", "surrogateescape")


def _jsonable(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: _jsonable(v) for k, v in data.items() if v is not None}
    if isinstance(data, list | tuple):
        return [_jsonable(v) for v in data]
    return data


BAT = tomllib.loads(GOOD_BAT)["bat"]
PROCEDURE = _jsonable(Procedure.load("bbcor").model_dump(mode="json"))
QUICK = {**PROCEDURE, **tomllib.loads(QUICK_PROCEDURE)["procedure"]}
QUICK["scan"] = {**PROCEDURE["scan"], "from_in": 6.5, "to_in": 7.0}
QUICK["hits"] = {**PROCEDURE["hits"], "valid_hits": 2}
SIM_PORTS = {d: f"sim://{d}?scene=ideal" for d in ("cannon", "gates", "clamp")}
RIG = _jsonable(RigConfig.from_dict({"ports": SIM_PORTS}).model_dump(mode="json"))
SCENE = _jsonable(Scene.load("lab").model_dump(mode="json"))


def _certify(files: dict[str, bytes], rig: list[str]) -> Result:
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        paths = {}
        for name, content in {
            "bat.toml": GOOD_BAT.encode(),
            "proc.toml": QUICK_PROCEDURE.encode(),
            **files,
        }.items():
            (d / name).write_bytes(content)
            paths[name] = str(d / name)
        db = d / "r.db"
        argv = ["certify", "--procedure", paths["proc.toml"], "--bat", paths["bat.toml"], "--db", str(db)]
        argv += [paths.get(a, a) for a in rig]
        return run_cli(argv, db)


@settings(max_examples=EXAMPLES)
@given(mutated(BAT, "bat"))
def test_bat_file(content: bytes) -> None:
    check(_certify({"bat.toml": content}, ["--sim", "ideal"]))


# Ports too: a port that cannot be opened is refused before the run is created (exit 2); a scene
# ball whose COR sends the aim beyond the calibration mid-run is an interruption on the record
# (exit 3), like any error during a run.
@settings(max_examples=EXAMPLES)
@given(mutated(RIG))
def test_rig_config_file(content: bytes) -> None:
    check(_certify({"rig.toml": content}, ["--config", "rig.toml"]))


@settings(max_examples=EXAMPLES)
@given(mutated(QUICK, "procedure"))
def test_procedure_file(content: bytes) -> None:
    check(_certify({"proc.toml": content}, ["--sim", "ideal"]))


@settings(max_examples=EXAMPLES)
@given(mutated(SCENE))
def test_scene_file(content: bytes) -> None:
    check(_certify({"scene.toml": content}, ["--sim", "scene.toml"]))


@cache
def _population_rows() -> list[list[str]]:
    text = (ROOT / "protocols" / "examples" / "population.csv").read_text()
    rows = list(csv.reader(line for line in text.splitlines() if line and not line.startswith("#")))
    return rows[:12]


@st.composite
def table_file(draw: st.DrawFn, rows: list[list[str]]) -> bytes:
    """A CSV: `rows` with one cell made extreme (or one row cut short), or binary garbage."""
    how = draw(st.sampled_from(["cell", "cell", "cell", "short", "garbage"]))
    if how == "garbage":
        return draw(st.binary(max_size=300))
    rows = [list(r) for r in rows]
    i = draw(st.integers(0, len(rows) - 1))
    j = draw(st.integers(0, len(rows[i]) - 1))
    if how == "short":
        rows[i] = rows[i][:j]
    else:
        rows[i][j] = str(draw(st.sampled_from(EXTREMES)))
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows(rows)
    return out.getvalue().encode("utf-8", "surrogateescape")


@settings(max_examples=EXAMPLES)
@given(table_file(_population_rows()))
def test_study_data_file(content: bytes) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "population.csv"
        path.write_bytes(content)
        check(run_cli(["rig-study", "population", "--data", str(path), "--json"]))


@cache
def _recording(suffix: str) -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"rec{suffix}"
        argv = ["modal", "simulate", str(path), "--hits", "2", "--interval", "0.1", "--hoop", "1800"]
        assert run_cli(argv).code == 0
        return path.read_bytes()


@st.composite
def recording_file(draw: st.DrawFn) -> tuple[str, bytes]:
    """A modal recording (CSV or UFF) with one line made extreme, cut short, or binary garbage."""
    suffix = draw(st.sampled_from([".csv", ".uff"]))
    how = draw(st.sampled_from(["line", "line", "truncate", "garbage"]))
    if how == "garbage":
        return suffix, draw(st.binary(max_size=300))
    lines = _recording(suffix).split(b"\n")
    i = draw(st.integers(0, min(len(lines) - 1, 80)))  # the header and the first samples
    if how == "truncate":
        return suffix, b"\n".join(lines[:i])
    value = str(draw(st.sampled_from(EXTREMES))).encode("utf-8", "surrogateescape")
    fields = lines[i].split(b",")
    fields[draw(st.integers(0, len(fields) - 1))] = value
    lines[i] = b",".join(fields) if len(fields) > 1 else value
    return suffix, b"\n".join(lines)


@settings(max_examples=EXAMPLES)
@given(recording_file())
def test_modal_recording_file(recording: tuple[str, bytes]) -> None:
    suffix, content = recording
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / f"rec{suffix}"
        path.write_bytes(content)
        check(run_cli(["modal", "analyze", str(path), "--json"]))


# Every numeric flag, in a command that is otherwise valid (FILE: a fresh file in a temporary
# directory; REC: a valid recording there). `rig sim serve --base-port` serves until stopped and
# `rig verify --anchor` is a text flag: both are tested elsewhere.
COMMANDS: list[tuple[list[str], list[str]]] = [
    (
        ["model", "cor", "--speed", "60", "--hoop", "1800", "--rtol", "1e-8", "--set", "m2=0.09"],
        ["--speed", "--hoop", "--rtol", "--set"],
    ),
    (["model", "cor", "--speed", "60", "--rigid"], ["--speed"]),
    (
        ["model", "curve", "--speed", "60", "--hoop-min", "500", "--hoop-max", "3000", "--points", "5"],
        ["--speed", "--hoop-min", "--hoop-max", "--points"],
    ),
    (
        ["model", "bat", "--speed", "60", "--hoop", "1800", "--moi", "0.2", "--impact-from-pivot", "0.55"],
        ["--speed", "--hoop", "--moi", "--impact-from-pivot"],
    ),
    (["rig-study", "accuracy", "--quick", "--repeats", "1"], ["--repeats"]),
    (
        ["shot", "--sim", "ideal", "--speed", "60", "--impact-from-pivot", "0.55", "--db", "FILE"],
        ["--speed", "--impact-from-pivot"],
    ),
    (
        [
            "modal",
            "simulate",
            "FILE",
            "--hits",
            "2",
            "--interval",
            "0.1",
            "--hoop",
            "1800",
            "--bending",
            "175",
            "--noise",
            "0.001",
            "--seed",
            "1",
            "--double-hit",
            "1",
            "--clip-force",
            "0.9",
        ],
        ["--hits", "--interval", "--hoop", "--bending", "--noise", "--seed", "--double-hit", "--clip-force"],
    ),
    (
        ["modal", "analyze", "REC", "--window", "0.05", "--max-resolution", "20", "--min-coherence", "0.9"],
        ["--window", "--max-resolution", "--min-coherence"],
    ),
]


@settings(max_examples=EXAMPLES)
@given(
    st.sampled_from([(argv, flag) for argv, flags in COMMANDS for flag in flags]),
    st.sampled_from(FLAG_EXTREMES),
)
def test_numeric_flag(command: tuple[list[str], str], value: str) -> None:
    argv, flag = command
    argv = list(argv)
    i = argv.index(flag) + 1
    argv[i] = f"k1={value}" if flag == "--set" else value
    with tempfile.TemporaryDirectory() as tmp:
        rec = Path(tmp) / "rec.csv"
        rec.write_bytes(_recording(".csv"))
        argv = [str(Path(tmp) / "out.csv") if a == "FILE" else str(rec) if a == "REC" else a for a in argv]
        check(run_cli(argv))

"""Hostile files through every file type the CLI reads: deeply nested, endless, oversized, binary.

The promise (issue 21, items 7 and 8): one line on stderr naming the file and the cause, exit 2,
no traceback, nothing read beyond a bound, no run left behind. Each file type is reached through
a command that reads it first or beside good files only, so the refusal must be the hostile
file's own. Endless inputs are /dev/zero, a FIFO whose writer never stops, and a sparse file far
larger than any bound (read, it would fill the memory).
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from tests.unit.clirun import GOOD_BAT, ROOT, Result, run_cli


@dataclass(frozen=True)
class Kind:
    """A file type and a command that reads it: FILE the hostile file, DB a fresh store, OUT an
    output file; a certification has a good bat, procedure and rig unless the kind is one."""

    name: str
    suffix: str
    syntax: str  # toml, json or csv: what nesting means in it
    command: tuple[str, ...]

    def __str__(self) -> str:
        return self.name

    def argv(self, target: str, folder: Path) -> list[str]:
        names = {"FILE": target, "DB": str(folder / "r.db"), "OUT": str(folder / "out.json")}
        out = [names.get(a, a) for a in self.command]
        if out[0] == "certify":
            for flag, value in (("--bat", str(folder / "bat.toml")), ("--procedure", "bbcor")):
                if flag not in out:
                    out += [flag, value]
            if "--sim" not in out and "--config" not in out:
                out += ["--sim", "ideal"]
        return out


MODEL_BAT = ("model", "bat", "--speed", "60", "--hoop", "2000", "--moi", "0.2", "--impact-from-pivot", "0.5")
KINDS = [
    Kind("bat", ".toml", "toml", ("certify", "--db", "DB", "--bat", "FILE")),
    Kind("procedure", ".toml", "toml", ("certify", "--db", "DB", "--procedure", "FILE")),
    Kind("ball-test procedure", ".toml", "toml",
         ("balls", "test", "--procedure", "FILE", "--lot", "L1", "--sim", "ideal", "--db", "DB")),
    Kind("rig config", ".toml", "toml", ("certify", "--db", "DB", "--config", "FILE")),
    Kind("scene", ".toml", "toml", ("certify", "--db", "DB", "--sim", "FILE")),
    Kind("population CSV", ".csv", "csv", ("model", "calibrate", "--data", "FILE", "--output", "OUT")),
    Kind("population TOML", ".toml", "toml", ("model", "calibrate", "--data", "FILE", "--output", "OUT")),
    Kind("study data", ".csv", "csv", ("rig-study", "population", "--data", "FILE")),
    Kind("calibration", ".json", "json", (*MODEL_BAT, "--calibration", "FILE")),
    Kind("certification calibration", ".json", "json", ("certify", "--db", "DB", "--calibration", "FILE")),
    Kind("ball file", ".json", "json", ("model", "cor", "--speed", "60", "--hoop", "2000", "--ball", "FILE")),
    Kind("lot file", ".toml", "toml", ("balls", "register", "FILE", "--db", "DB")),
    Kind("CCOR data", ".csv", "csv", ("model", "fit-ball", "--data", "FILE", "--output", "OUT")),
    Kind("modal recording CSV", ".csv", "csv", ("modal", "analyze", "FILE")),
    Kind("modal recording UFF", ".uff", "csv", ("modal", "analyze", "FILE")),
]  # fmt: skip


def nested(syntax: str, depth: int, shape: str = "array") -> bytes:
    """A document nested `depth` levels deep: arrays, tables/objects, or (TOML) a dotted header."""
    if syntax == "json":
        if shape == "array":
            return ("[" * depth + "]" * depth).encode()
        return ('{"a":' * depth + "1" + "}" * depth).encode()
    if shape == "header":
        return ("[" + ".".join(["a"] * depth) + "]\nx = 1\n").encode()
    inner = "[" * depth + "]" * depth if shape == "array" else "{a=" * depth + "1" + "}" * depth
    return f"x = {inner}\n".encode()


@contextlib.contextmanager
def endless_fifo(path: Path) -> Iterator[Path]:
    """A FIFO whose writer (holding it open read-write, so that no open blocks) never stops."""
    os.mkfifo(path)
    fd = os.open(path, os.O_RDWR | os.O_NONBLOCK)
    stop = threading.Event()
    block = b"x = 1\n" * 10_000

    def feed() -> None:
        while not stop.is_set():
            if select.select([], [fd], [], 0.05)[1]:
                with contextlib.suppress(BlockingIOError):
                    os.write(fd, block)

    thread = threading.Thread(target=feed, daemon=True)
    thread.start()
    try:
        yield path
    finally:
        stop.set()
        thread.join(5)
        os.close(fd)


def run(kind: Kind, folder: Path, target: str) -> Result:
    """The kind's command on `target`, beside a good bat, in `folder`."""
    (folder / "bat.toml").write_text(GOOD_BAT, encoding="utf-8")
    db = folder / "r.db"
    return run_cli(kind.argv(target, folder), db)


def refused(result: Result, target: str) -> None:
    """Exit 2, one line naming the file, no traceback, no run left running."""
    assert "Traceback" not in result.err, result.err
    lines = result.err.strip().splitlines()
    assert result.code == 2, (result.code, result.err[-2000:])
    assert len(lines) == 1, result.err[-2000:]
    assert len(lines[0]) < 600, lines[0]
    assert target in lines[0], lines[0]
    assert result.stray_runs == []


SHAPES = {"toml": ("array", "table", "header"), "json": ("array", "table"), "csv": ()}


@pytest.mark.parametrize(("kind", "shape"), [(k, s) for k in KINDS for s in SHAPES[k.syntax]], ids=str)
def test_a_deeply_nested_file_is_refused_in_one_line(kind: Kind, shape: str, tmp_path: Path) -> None:
    path = tmp_path / f"hostile{kind.suffix}"
    path.write_bytes(nested(kind.syntax, 5000, shape))
    result = run(kind, tmp_path, str(path))
    refused(result, str(path))
    assert "nested" in result.err


@pytest.mark.parametrize("kind", [k for k in KINDS if k.syntax != "csv"], ids=str)
def test_nesting_the_parser_survives_is_refused_too(kind: Kind, tmp_path: Path) -> None:
    """Deep enough to crash what comes after the parser (validation, JSON in the store), not it."""
    path = tmp_path / f"hostile{kind.suffix}"
    depth = 800 if kind.syntax == "json" else 3000
    path.write_bytes(nested(kind.syntax, depth, "table" if kind.syntax == "json" else "header"))
    result = run(kind, tmp_path, str(path))
    refused(result, str(path))
    assert "nested" in result.err


@pytest.mark.parametrize("kind", KINDS, ids=str)
def test_dev_zero_is_refused_by_its_size(kind: Kind, tmp_path: Path) -> None:
    result = run(kind, tmp_path, "/dev/zero")
    refused(result, "/dev/zero")
    assert "larger than" in result.err


@pytest.mark.parametrize("kind", KINDS, ids=str)
def test_an_endless_fifo_is_refused_by_its_size(kind: Kind, tmp_path: Path) -> None:
    with endless_fifo(tmp_path / f"fifo{kind.suffix}") as path:
        result = run(kind, tmp_path, str(path))
    refused(result, str(path))
    assert "larger than" in result.err


@pytest.mark.parametrize("kind", KINDS, ids=str)
def test_a_huge_file_is_refused_without_reading_it(kind: Kind, tmp_path: Path) -> None:
    path = tmp_path / f"huge{kind.suffix}"
    with path.open("wb") as fh:
        fh.truncate(1 << 34)  # 16 GiB, sparse: read, it would fill the memory
    result = run(kind, tmp_path, str(path))
    refused(result, str(path))
    assert "larger than" in result.err


# --- Hypothesis: any mix of the above, and binary or malformed bytes, for any file type ----------

SPECIAL = ["/dev/zero", "fifo", "huge", "directory", "empty"]


@st.composite
def hostile(draw: st.DrawFn) -> tuple[str, bytes | str]:
    """(how, content): nested text, binary bytes, bytes that are not UTF-8, or a SPECIAL file."""
    how = draw(st.sampled_from(["nested", "nested", "binary", "latin", "long line", "special"]))
    if how == "nested":
        syntax = draw(st.sampled_from(["toml", "json"]))
        shapes = ["array", "table", "header"] if syntax == "toml" else ["array", "table"]
        depth = draw(st.one_of(st.integers(40, 200), st.integers(200, 20_000)))
        prefix = draw(st.sampled_from([b"", b"[bat]\n", b"[procedure]\n", b"[lot]\n"]))
        return how, prefix + nested(syntax, depth, draw(st.sampled_from(shapes)))
    if how == "binary":
        return how, draw(st.binary(min_size=1, max_size=2000)) + b"\x00"
    if how == "latin":
        return how, draw(st.binary(min_size=1, max_size=200)) + b"x = \xe9\xff\n"
    if how == "long line":
        return how, b"a" * draw(st.integers(200_000, 2_000_000)) + b"\n"
    return "special", draw(st.sampled_from(SPECIAL))


@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(kind=st.sampled_from(KINDS), hostile=hostile())
def test_any_hostile_file_of_any_type_is_refused_in_one_line(
    kind: Kind, hostile: tuple[str, bytes | str], tmp_path_factory: pytest.TempPathFactory
) -> None:
    _, content = hostile
    folder = tmp_path_factory.mktemp("hostile")
    path = folder / f"hostile{kind.suffix}"
    with contextlib.ExitStack() as stack:
        if isinstance(content, bytes):
            path.write_bytes(content)
            target = str(path)
        elif content == "/dev/zero":
            target = content
        elif content == "fifo":
            target = str(stack.enter_context(endless_fifo(path)))
        elif content == "huge":
            with path.open("wb") as fh:
                fh.truncate(1 << 34)
            target = str(path)
        elif content == "directory":
            path.mkdir()
            target = str(path)
        else:  # empty: a scene of nothing but defaults is a valid scene, nothing else is
            assume(kind.name != "scene")
            path.write_bytes(b"")
            target = str(path)
        result = run(kind, folder, target)
    refused(result, target)


def test_every_file_type_of_the_cli_is_in_the_table() -> None:
    """The readers this test must reach (a new file type belongs in KINDS)."""
    names = {k.name for k in KINDS}
    assert {"bat", "procedure", "ball-test procedure", "rig config", "scene", "calibration", "ball file",
            "lot file", "CCOR data", "study data", "modal recording CSV"} <= names  # fmt: skip
    assert (ROOT / "protocols" / "examples" / "population.csv").is_file()

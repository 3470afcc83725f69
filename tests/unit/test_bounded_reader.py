"""rig.core.files: the one reader every input file goes through (bounded, non-recursive)."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from rig.core.errors import ConfigError, listed, shown
from rig.core.files import MAX_DEPTH, check_nesting, parse_json, parse_toml, read_bounded, read_text


def test_dev_zero_is_read_one_byte_past_the_bound_and_no_further() -> None:
    with pytest.raises(ConfigError, match=r"^/dev/zero: not a bat file: larger than 1000 bytes \(a device"):
        read_bounded("/dev/zero", 1000, "a bat file")


def test_a_fifo_nobody_writes_reads_as_empty_rather_than_waiting(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(read_bounded(fifo, 100, "a bat file")), daemon=True)
    reader.start()
    reader.join(10)
    assert got == [b""]


def test_a_huge_regular_file_is_refused_by_its_size_unread(tmp_path: Path) -> None:
    huge = tmp_path / "huge.toml"
    with huge.open("wb") as fh:
        fh.truncate(1 << 40)  # 1 TiB, sparse
    with pytest.raises(ConfigError, match=r"larger than 100 bytes$"):
        read_bounded(huge, 100, "a bat file")


@pytest.mark.parametrize(
    ("make", "needle"),
    [
        (lambda p: p.mkdir(), "a directory"),
        (lambda p: p.write_bytes(b"x = 1\x00"), "NUL bytes"),
        (lambda p: None, "no such file"),
    ],
)
def test_refusals_name_the_file(tmp_path: Path, make, needle: str) -> None:
    path = tmp_path / "f.toml"
    make(path)
    with pytest.raises(ConfigError) as info:
        read_bounded(path, 100, "a bat file")
    assert str(info.value).startswith(str(path)) and needle in str(info.value)


def test_binary_files_may_hold_nul_and_text_must_be_utf8(tmp_path: Path) -> None:
    path = tmp_path / "f.uff"
    path.write_bytes(b"\x00\xff")
    assert read_bounded(path, 100, "a recording", binary=True) == b"\x00\xff"
    with pytest.raises(ConfigError, match=r"not a bat file: not UTF-8 text \(byte 1\)"):
        path.write_bytes(b"a\xff")
        read_text(path, 100, "a bat file")


@pytest.mark.parametrize(
    "text",
    [
        "x = " + "[" * 5000 + "]" * 5000,
        "x = " + "{a=" * 5000 + "1" + "}" * 5000,
        "[" + ".".join(["a"] * 5000) + "]\n",  # tomllib survives this; what walks the data after it need not
        "[" + ".".join(["a"] * (MAX_DEPTH + 1)) + "]\n",
    ],
)
def test_toml_nested_too_deeply_is_refused(text: str) -> None:
    with pytest.raises(
        ConfigError, match=f"^bat.toml: not a bat file: nested more than {MAX_DEPTH} levels deep$"
    ):
        parse_toml(text, "bat.toml", "a bat file")


def test_json_nested_too_deeply_is_refused() -> None:
    for text in ("[" * 100_000 + "]" * 100_000, '{"a":' * 900 + "1" + "}" * 900, "[" * 33 + "]" * 33):
        with pytest.raises(ConfigError, match="nested more than"):
            parse_json(text, "cal.json", "a calibration file")
    assert parse_json("[" * 32 + "]" * 32, "cal.json") is not None


def test_other_parse_errors_are_one_line() -> None:
    with pytest.raises(ConfigError, match=r"^b\.toml: not valid TOML: "):
        parse_toml("x = ", "b.toml")
    with pytest.raises(ConfigError, match=r"^c\.json: not a calibration file: Exceeds the limit"):
        parse_json("1" * 5000, "c.json", "a calibration file")


def test_check_nesting_does_not_recurse() -> None:
    deep: list = []
    for _ in range(100_000):
        deep = [deep]
    with pytest.raises(ConfigError, match="nested more than 32"):
        check_nesting(deep, "x", "a file")
    check_nesting({"a": [{"b": [1, 2]}]}, "x", "a file")


def test_messages_quote_a_hostile_value_short() -> None:
    assert shown("a" * 10**6) == "'" + "a" * 55 + "...'"
    assert shown(1.5) == "1.5"
    assert listed(["a", "b"]) == "a, b"
    assert listed([str(i) for i in range(10)]) == "0, 1, 2, 3, 4, 5 and 4 more"
    assert len(listed(["x" * 10**6])) < 50

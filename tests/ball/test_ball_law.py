"""The ball-law file (rig.physics.ball_law): round trip, atomic save, hostile files refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rig.core.errors import ConfigError
from rig.physics import DEFAULT_PARAMS
from rig.physics.ball_law import BallLaw, BallProvenance


def law(**changes: object) -> BallLaw:
    constants = {"m1": 0.145, "k1": 6e7, "c1": 5000.0, "a": 0.7, "b": 0.55}
    base = {
        "constants": constants,
        "variant": "a+b",
        "parameters": {"a": 0.7, "b": 0.55},
        "uncertainty": {"a": 0.05, "b": 0.03},
        "covariance": [[0.0025, 0.0015], [0.0015, 0.0009]],
        "correlation_ab": 1.0,
        "scatter": 0.0005,
        "loo_rmse": 0.0006,
        "dof": 18,
        "weighting": "equal",
        "selection": "loo",
        "provenance": BallProvenance(
            data_file="ccor.csv",
            data_sha256="0" * 64,
            lot="L1",
            n_points=20,
            n_balls=20,
            n_speeds=5,
            speed_min_m_s=25.0,
            speed_max_m_s=60.0,
            created_utc="2026-01-01T00:00:00+00:00",
            software="rig 0.1.0",
        ),
    }
    return BallLaw.model_validate({**base, **changes})


def test_round_trip_and_params(tmp_path: Path) -> None:
    path = law().save(tmp_path / "sub" / "ball.json")
    back, sha = BallLaw.read(path)
    assert back == law() and len(sha) == 64
    assert back.params == DEFAULT_PARAMS.model_copy(update={"a": 0.7, "b": 0.55})
    assert back.apply(DEFAULT_PARAMS.model_copy(update={"m2": 0.2})).m2 == 0.2
    assert [p.name for p in path.parent.iterdir()] == ["ball.json"]  # no temporary file left


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        (b"\x00\x01binary", "NUL bytes"),
        (b"{not json", "not a ball file: Expecting property name"),
        (b"\xff\xfe", "not a ball file"),
        (b'{"kind": "rig-model-calibration"}', "its kind is not 'rig-ball-law'"),
        (b"[1, 2]", "its kind is not"),
        (b"[" * 100000 + b"]" * 100000, "not a ball file"),
    ],
)
def test_hostile_files_are_refused(tmp_path: Path, content: bytes, needle: str) -> None:
    path = tmp_path / "ball.json"
    path.write_bytes(content)
    with pytest.raises(ConfigError, match=None) as info:
        BallLaw.load(path)
    assert needle in str(info.value) and str(path) in str(info.value) and "\n" not in str(info.value)


def test_bad_values_are_refused_naming_the_field(tmp_path: Path) -> None:
    good = json.loads(law().to_json())
    cases = [
        ({**good, "constants": {**good["constants"], "a": 1.5}}, "a = 1.5: must lie within 0-1"),
        ({**good, "constants": {"a": 0.7}}, "constants must be exactly m1, k1, c1, a, b"),
        ({**good, "covariance": [[1.0]]}, "covariance must be 2 x 2"),
        ({**good, "parameters": {"a": 0.71, "b": 0.55}}, "differs from the constant"),
        ({**good, "scatter": "NaN"}, "scatter: Input should be a finite number"),
        ({**good, "surprise": 1}, "surprise"),
    ]
    for data, needle in cases:
        path = tmp_path / "ball.json"
        path.write_text(json.dumps(data), encoding="utf-8")
        with pytest.raises(ConfigError) as info:
            BallLaw.load(path)
        assert needle in str(info.value), (needle, str(info.value))


def test_missing_huge_and_directory(tmp_path: Path) -> None:
    huge = tmp_path / "huge.json"
    with huge.open("wb") as fh:
        fh.truncate(5_000_000)
    for path, needle in (
        (tmp_path / "absent.json", "no such file"),
        (huge, "larger than"),
        (tmp_path, "directory"),
    ):
        with pytest.raises(ConfigError, match=needle):
            BallLaw.load(path)

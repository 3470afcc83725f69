"""rig.core.tomlfile.dump_toml: what it writes, tomllib reads back equal (a rig config that
`rig sim serve --write-config` writes is read by `rig certify --config`)."""

from __future__ import annotations

import json
import math
import tomllib

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rig.core.config import RigConfig
from rig.core.tomlfile import dump_toml
from rig.session import sim_config

keys = st.text(min_size=1, max_size=12)
scalars = st.one_of(
    st.booleans(),
    st.integers(-(2**63), 2**63 - 1),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=20),
)
leaf = st.one_of(scalars, st.lists(scalars, max_size=4))
options = st.dictionaries(keys, leaf, max_size=4)


def tables(depth: int) -> st.SearchStrategy[dict]:
    inner = st.dictionaries(keys, leaf, max_size=4)
    if depth > 0:
        inner = st.dictionaries(keys, st.one_of(leaf, tables(depth - 1)), max_size=4)
    return st.one_of(inner, st.fixed_dictionaries({"options": options}, optional={"x": leaf}))


def _same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.copysign(1, a) == math.copysign(1, b) and a == b)
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return type(a) is type(b) and a == b


@given(tables(2))
def test_what_it_writes_reads_back_equal(data: dict) -> None:
    assert _same(tomllib.loads(dump_toml(data)), data)


def test_a_simulated_rig_config_round_trips_through_its_toml() -> None:
    config = sim_config("lab")
    data = json.loads(config.model_dump_json(exclude_none=True))
    assert RigConfig.from_dict(tomllib.loads(dump_toml(data))) == config


@pytest.mark.parametrize("bad", [math.nan, math.inf, object()])
def test_a_value_toml_cannot_hold_is_refused_naming_its_key(bad: object) -> None:
    with pytest.raises(ValueError, match=r"^devices.gates.level: "):
        dump_toml({"devices": {"gates": {"level": bad}}})

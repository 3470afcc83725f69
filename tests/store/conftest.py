"""Fixtures for the store tests: a fresh store, a populated one, and raw access for tampering."""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import pytest

from rig.store import Store


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    """An empty store of chain format 1 (the one chain that files written before format 2 keep,
    whose tampering tests count seqs); format 2 is tested in test_chains.py."""
    with Store.open(tmp_path / "rig.db", chain_format=1) as s:
        yield s


@pytest.fixture
def store2(tmp_path: Path) -> Iterator[Store]:
    """An empty store of chain format 2 (a chain per run and the lab's): what new files are."""
    with Store.open(tmp_path / "rig2.db") as s:
        assert s.chain_format == 2
        yield s


@dataclass(frozen=True)
class Populated:
    """A store with one bat, two runs (one finished) and a rig-level entry between them."""

    store: Store
    run_a: str
    run_b: str


def populate(store: Store, shots: int = 4) -> Populated:
    """Fill `store`: seq 1 bat, 2 run A, 3..2+shots shots, a note, run B, a shot, A finished."""
    store.register_bat("B-1", {"model": "X33", "length_in": 33, "weight_oz": 30})
    run_a = store.create_run("bbcor", "B-1", {"operator": "ann"})
    for i in range(shots):
        store.append(run_a, "ShotMeasured", {"shot": i, "v_in_m_s": 61.0 + i / 10})
    store.append(None, "Note", {"text": "coffee"})
    run_b = store.create_run("besr", "B-1", {"operator": "bob"})
    store.append(run_b, "ShotFired", {"shot": 0})
    store.set_run_status(run_a, "finished", "pass")
    return Populated(store, run_a, run_b)


@pytest.fixture
def populated(store: Store) -> Populated:
    """`store` after `populate` (10 entries)."""
    return populate(store)


@contextmanager
def raw(path: Path) -> Iterator[sqlite3.Connection]:
    """A plain connection with the append-only triggers lifted, restored on exit (as a forger would)."""
    conn = sqlite3.connect(path, isolation_level=None)
    triggers = conn.execute("SELECT name, sql FROM sqlite_master WHERE type = 'trigger'").fetchall()
    for name, _ in triggers:
        conn.execute(f"DROP TRIGGER {name}")
    try:
        yield conn
    finally:
        for _, sql in triggers:
            conn.execute(sql)
        conn.close()

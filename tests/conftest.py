"""Shared test set-up: Hypothesis profiles and the collision model's default constants.

Profiles (choose with HYPOTHESIS_PROFILE, default "ci"):
- "ci": few examples, no deadline (the first call may load the compiled kernel), derandomized so
  that a CI run is reproducible, no example database written into the checkout;
- "dev": many random examples, for hunting new hard cases locally.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, settings

from rig.physics.params import DEFAULT_PARAMS, CollisionParams
from tests.load import ROOT_ENV
from tests.load import cpu_load as _cpu_load
from tests.pgfixtures import (
    pg_cluster,
    pg_url,
    pytest_sessionfinish,
    pytest_terminal_summary,
    pytest_testnodedown,
)

__all__ = [  # PostgreSQL: tests/pgfixtures.py
    "pg_cluster",
    "pg_url",
    "pytest_sessionfinish",
    "pytest_terminal_summary",
    "pytest_testnodedown",
]

settings.register_profile(
    "ci",
    max_examples=50,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "dev",
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))


@pytest.fixture(scope="session")
def paper_params() -> CollisionParams:
    """The founding paper's constants (ball 0.145 kg, barrel 0.09 kg, a = 0.6495, b = 0.5202)."""
    return DEFAULT_PARAMS


@pytest.fixture(autouse=True)
def _private_key_dir(tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch) -> None:
    """Rig keys (rig.keys) go to an empty folder of each test's own, never the user's."""
    monkeypatch.setenv("RIG_KEY_DIR", str(tmp_path_factory.mktemp("rig-keys")))


# SIGINT and SIGTERM as the test process started with them
SIGNAL_DISPOSITIONS = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}


@pytest.fixture(autouse=True)
def _signal_dispositions_restored() -> Iterator[None]:
    """A CLI run in this process (in a test or a module's fixture) leaves SIGINT and SIGTERM
    ignored (rig.run_signals: it is reporting its outcome and exiting); an ignored signal is
    inherited by every child a later test starts, which then cannot be terminated. Each test
    starts, and leaves, with the dispositions the test process started with."""
    for s, handler in SIGNAL_DISPOSITIONS.items():
        signal.signal(s, handler)
    yield
    for s, handler in SIGNAL_DISPOSITIONS.items():
        signal.signal(s, handler)


@pytest.fixture
def cpu_load() -> Iterator[None]:
    """Two CPU-bound processes beside the test (tests/load.py): for tests that cross a process boundary."""
    with _cpu_load():
        yield


def pytest_configure(config: pytest.Config) -> None:
    """The test run's first process (the controller under pytest-xdist, whose workers inherit it):
    the processes of the run that count as load beside a test in `cpu_load` are its descendants."""
    os.environ.setdefault(ROOT_ENV, str(os.getpid()))


def pytest_addoption(parser: pytest.Parser) -> None:
    """--hardware RIG.toml: also run the tests marked `hardware` against that real rig."""
    parser.addoption(
        "--hardware",
        metavar="RIG.toml",
        default=None,
        help="run the hardware tests against the rig this config file describes (never fires)",
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests that use the PostgreSQL cluster are marked `postgres` (so `-m "not postgres"` leaves
    them out); hardware tests are opt-in: skipped unless --hardware names a rig config."""
    for item in items:
        if "pg_cluster" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.postgres)
    if config.getoption("--hardware"):
        return
    skip = pytest.mark.skip(reason="needs the real rig: pytest --hardware RIG.toml")
    for item in items:
        if "hardware" in item.keywords:
            item.add_marker(skip)

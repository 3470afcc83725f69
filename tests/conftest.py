"""Shared test set-up: Hypothesis profiles and the collision model's default constants.

Profiles (choose with HYPOTHESIS_PROFILE, default "ci"):
- "ci": few examples, no deadline (the first call may load the compiled kernel), derandomized so
  that a CI run is reproducible, no example database written into the checkout;
- "dev": many random examples, for hunting new hard cases locally.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, settings

from rig.physics.params import DEFAULT_PARAMS, CollisionParams
from tests.load import cpu_load as _cpu_load
from tests.pgcluster import INSTALL_HINT, ClusterError, PgCluster, find_bin_dir, throwaway_cluster

_clusters: list[PgCluster] = []  # the session's PostgreSQL cluster, once a test asked for it

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


@pytest.fixture
def cpu_load() -> Iterator[None]:
    """Two CPU-bound processes beside the test (tests/load.py): for tests that cross a process boundary."""
    with _cpu_load():
        yield


@pytest.fixture(scope="session")
def pg_cluster() -> Iterator[PgCluster]:
    """A throwaway PostgreSQL cluster for the session (tests/pgcluster.py); skipped where the server
    binaries are missing, failed instead when RIG_REQUIRE_POSTGRES=1 (CI)."""
    required = os.environ.get("RIG_REQUIRE_POSTGRES") == "1"
    bin_dir = find_bin_dir()
    if bin_dir is None:
        if required:
            pytest.fail(f"{INSTALL_HINT} (RIG_REQUIRE_POSTGRES=1: PostgreSQL tests must run)", pytrace=False)
        pytest.skip(INSTALL_HINT)
    with contextlib.ExitStack() as stack:
        try:
            cluster = stack.enter_context(throwaway_cluster(bin_dir))
        except ClusterError as exc:
            pytest.fail(f"throwaway PostgreSQL cluster: {exc}", pytrace=False)
        _clusters.append(cluster)
        yield cluster


@pytest.fixture
def pg_url(pg_cluster: PgCluster) -> Iterator[str]:
    """A fresh empty database for this test: postgresql://USER:PW@127.0.0.1:PORT/DB; dropped after."""
    name = pg_cluster.create_db()
    yield pg_cluster.url(name)
    if not pg_cluster.running:  # the test stopped the server and did not bring it back
        pg_cluster.start()
    pg_cluster.drop_db(name)


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """One line on what the PostgreSQL cluster cost the session, if one was started."""
    for c in _clusters:
        made = sorted(c.create_times)
        median = f", median {made[len(made) // 2] * 1e3:.0f} ms each" if made else ""
        terminalreporter.write_line(
            f"PostgreSQL test cluster ({c.bin_dir}): up in {c.timings.get('up', 0.0):.2f} s "
            f"(initdb {c.timings.get('initdb', 0.0):.2f} s), {len(made)} databases created{median}"
        )


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

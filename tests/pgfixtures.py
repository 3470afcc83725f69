"""pytest fixtures for the throwaway PostgreSQL cluster (tests/pgcluster.py).

tests/conftest.py imports them for the whole suite; an inner pytest run that needs nothing else
loads this module alone with `-p tests.pgfixtures`.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.pgcluster import INSTALL_HINT, ClusterError, PgCluster, find_bin_dir, throwaway_cluster

_clusters: list[PgCluster] = []  # the session's PostgreSQL cluster, once a test asked for it


def require_bin_dir() -> Path:
    """The server binaries' folder; else skip, or fail when RIG_REQUIRE_POSTGRES=1, saying how to install."""
    bin_dir = find_bin_dir()
    if bin_dir is None:
        if os.environ.get("RIG_REQUIRE_POSTGRES") == "1":
            pytest.fail(f"{INSTALL_HINT} (RIG_REQUIRE_POSTGRES=1: PostgreSQL tests must run)", pytrace=False)
        pytest.skip(INSTALL_HINT)
    return bin_dir


@pytest.fixture(scope="session")
def pg_cluster() -> Iterator[PgCluster]:
    """A throwaway PostgreSQL cluster for the session (tests/pgcluster.py); skipped where the server
    binaries are missing, failed instead when RIG_REQUIRE_POSTGRES=1 (CI)."""
    bin_dir = require_bin_dir()
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
    if pg_cluster.stopped:  # the test stopped the server and did not bring it back
        pg_cluster.start()
    pg_cluster.drop_db(name)


_reported: list[str] = []  # summary lines from the test workers (pytest-xdist), on the controller


def _summary_lines() -> list[str]:
    lines = []
    for c in _clusters:
        made = sorted(c.create_times)
        median = f", median {made[len(made) // 2] * 1e3:.0f} ms each" if made else ""
        lines.append(
            f"PostgreSQL test cluster ({c.bin_dir}): up in {c.timings.get('up', 0.0):.2f} s "
            f"(initdb {c.timings.get('initdb', 0.0):.2f} s), {len(made)} databases created{median}"
        )
    return lines


def pytest_sessionfinish(session: pytest.Session) -> None:
    """A test worker (pytest-xdist) hands its cluster's line to the controller, which prints it."""
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:
        workeroutput["pg_cluster_summary"] = _summary_lines()


@pytest.hookimpl(optionalhook=True)  # a pytest-xdist hook: absent when the plugin is not loaded
def pytest_testnodedown(node: object, error: object) -> None:
    """The controller collects the lines its workers handed over."""
    _reported.extend(getattr(node, "workeroutput", {}).get("pg_cluster_summary", []))


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """One line per PostgreSQL cluster the session (or each of its workers) started."""
    for line in [*_reported, *_summary_lines()]:
        terminalreporter.write_line(line)

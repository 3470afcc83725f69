"""The throwaway PostgreSQL cluster the store tests run against (tests/pgcluster.py).

Every check goes through the server itself (psycopg over TCP, the server's own view of who and
where it is), never through the cluster object's idea of itself. Each test runs with two
CPU-bound processes beside it: the server is another process.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from urllib.parse import urlsplit

import psycopg
import pytest

from tests.pgcluster import PgCluster, find_bin_dir
from tests.pgfixtures import require_bin_dir

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.usefixtures("cpu_load")


def _connect(url: str) -> psycopg.Connection[tuple[object, ...]]:
    return psycopg.connect(url, connect_timeout=30, autocommit=True)


def test_cluster_starts_and_psycopg_connects_over_tcp(pg_cluster: PgCluster, pg_url: str) -> None:
    parts = urlsplit(pg_url)
    assert (parts.scheme, parts.hostname, parts.port) == ("postgresql", "127.0.0.1", pg_cluster.port)
    with _connect(pg_url) as conn:
        row = conn.execute(
            "SELECT current_user, current_database(), host(inet_server_addr()), inet_server_port(),"
            " current_setting('server_version_num')::int / 10000"
        ).fetchone()
    # the server's own account: the login role, the database named in the URL, over TCP (a unix
    # socket connection has no server address), the major version of the binaries' folder
    assert row == (
        parts.username,
        parts.path[1:],
        "127.0.0.1",
        parts.port,
        int(pg_cluster.bin_dir.parent.name),
    )
    took = pg_cluster.timings
    print(
        f"\nPostgreSQL cluster up in {took['up']:.2f} s"
        f" (initdb {took['initdb']:.2f} s, start {took['start']:.2f} s);"
        f" this test's database created in {pg_cluster.create_times[-1] * 1e3:.0f} ms"
    )


def test_two_test_databases_are_separate(pg_cluster: PgCluster, pg_url: str) -> None:
    other = pg_cluster.url(pg_cluster.create_db())
    assert urlsplit(other).path != urlsplit(pg_url).path
    with _connect(pg_url) as a, _connect(other) as b:
        a.execute("CREATE TABLE log (seq int PRIMARY KEY, body text)")
        a.execute("INSERT INTO log VALUES (1, 'only here')")
        assert b.execute("SELECT to_regclass('log')").fetchone() == (None,)
        b.execute("CREATE TABLE log (seq int PRIMARY KEY, body text)")  # same name, no clash
        assert b.execute("SELECT count(*) FROM log").fetchone() == (0,)
        assert a.execute("SELECT body FROM log").fetchall() == [("only here",)]
    pg_cluster.drop_db(urlsplit(other).path[1:])


def test_a_fresh_database_is_empty_and_owned_by_the_login_role(pg_cluster: PgCluster, pg_url: str) -> None:
    with _connect(pg_url) as conn:
        tables = conn.execute(
            "SELECT count(*) FROM pg_tables WHERE schemaname NOT IN ('pg_catalog', 'information_schema')"
        ).fetchone()
        owner = conn.execute(
            "SELECT pg_get_userbyid(datdba) FROM pg_database WHERE datname = current_database()"
        ).fetchone()
    assert tables == (0,)
    assert owner == (pg_cluster.user,)


def test_a_wrong_password_is_refused(pg_cluster: PgCluster, pg_url: str) -> None:
    dbname = urlsplit(pg_url).path[1:]
    with pytest.raises(psycopg.OperationalError, match="password authentication failed") as refused:
        _connect(pg_cluster.url(dbname, password="not-the-password"))
    assert pg_cluster.user in str(refused.value)
    with _connect(pg_url) as conn:  # the right one, to the same database, is let in
        assert conn.execute("SELECT 1").fetchone() == (1,)


@pytest.mark.parametrize("mode", ["fast", "immediate"])
def test_stop_refuses_connections_and_start_brings_the_same_data_back(
    pg_cluster: PgCluster, pg_url: str, mode: str
) -> None:
    with _connect(pg_url) as conn:
        conn.execute("CREATE TABLE log (seq int PRIMARY KEY, body text)")
        conn.execute("INSERT INTO log VALUES (1, 'before the outage'), (2, 'committed')")
        pid_before = conn.info.backend_pid
        pg_cluster.stop(mode)
        assert not pg_cluster.running and pg_cluster.stopped
        with pytest.raises(psycopg.OperationalError):  # the open connection is gone
            conn.execute("SELECT 1")
    with pytest.raises(psycopg.OperationalError, match=r"(?i)connection refused|connection failed"):
        psycopg.connect(pg_url, connect_timeout=5)
    pg_cluster.start()
    with _connect(pg_url) as conn:
        assert conn.info.port == pg_cluster.port == urlsplit(pg_url).port
        assert conn.execute("SELECT seq, body FROM log ORDER BY seq").fetchall() == [
            (1, "before the outage"),
            (2, "committed"),
        ]
        assert conn.info.backend_pid != pid_before  # a new server process, not a surviving one


def test_the_newest_server_version_is_chosen_and_pg_bin_wins(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def install(version: str, tools: tuple[str, ...] = ("initdb", "pg_ctl", "pg_isready")) -> Path:
        folder = tmp_path / version / "bin"
        folder.mkdir(parents=True)
        for tool in tools:
            (folder / tool).write_text("#!/bin/sh\n")
            (folder / tool).chmod(0o755)
        return folder

    monkeypatch.delenv("PG_BIN", raising=False)
    install("9.6")
    fifteen = install("15")
    install("16", tools=("initdb", "pg_ctl"))  # incomplete: no pg_isready
    assert find_bin_dir(tmp_path) == fifteen  # 15 > 9.6 as numbers, though "9.6" > "15" as text
    monkeypatch.setenv("PG_BIN", str(tmp_path / "9.6" / "bin"))
    assert find_bin_dir(tmp_path) == tmp_path / "9.6" / "bin"
    monkeypatch.setenv("PG_BIN", str(tmp_path / "nowhere"))
    assert find_bin_dir(tmp_path) is None


# -- the session's life cycle, seen from outside: an inner pytest run with its own cluster ----------

INNER_TEST = textwrap.dedent("""
    import time

    def test_uses_postgres(pg_cluster, pg_url):
        print("ROOT", pg_cluster.root, flush=True)
        time.sleep(60)  # the outer test ends this run first (Ctrl-C or kill -9)
""")


def _inner_pytest(tmp_path: Path) -> subprocess.Popen[str]:
    test = tmp_path / "test_inner.py"
    test.write_text(INNER_TEST)
    return subprocess.Popen(
        [sys.executable, "-m", "pytest", "-c", str(ROOT / "pyproject.toml"), "--rootdir", str(ROOT),
         "-p", "tests.pgfixtures", "-p", "no:cacheprovider", "-s", "-q", str(test)],
        cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT), "PYTEST_DISABLE_PLUGIN_AUTOLOAD": "1"},
        stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip


def _postmaster_pid(root: Path) -> int:
    return int((root / "data" / "postmaster.pid").read_text().split()[0])


def _alive(pid: int) -> bool:
    """A live process (a zombie no init has reaped yet counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def _wait_for_root(proc: subprocess.Popen[str]) -> Path:
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.startswith("ROOT "):
            return Path(line.split(maxsplit=1)[1].strip())
    raise AssertionError(f"the inner run never reached its test (exit {proc.wait()})")


def _gone_within(root: Path, pid: int, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while not (gone := not root.exists() and not _alive(pid)) and time.monotonic() < deadline:
        time.sleep(0.2)
    return gone


@pytest.mark.postgres
@pytest.mark.parametrize("how", ["ctrl-c", "kill -9"])
def test_the_cluster_is_stopped_and_deleted_however_the_session_ends(tmp_path: Path, how: str) -> None:
    require_bin_dir()  # skip, or fail in CI, as the fixtures do where the server binaries are missing
    proc = _inner_pytest(tmp_path)
    try:
        root = _wait_for_root(proc)
        server = _postmaster_pid(root)
        assert _alive(server)  # it was really running
        if how == "ctrl-c":
            os.killpg(proc.pid, signal.SIGINT)
        elif how == "kill -9":
            os.kill(proc.pid, signal.SIGKILL)  # no finaliser runs: the watchdog must clean up
        proc.wait(timeout=120)
        # Ctrl-C: pytest's finaliser stops and deletes it before pytest exits (the watchdog would
        # take another half second); kill -9: the watchdog is left to do it
        within = 0.0 if how == "ctrl-c" else 60.0
        assert _gone_within(root, server, within), f"{root} or its server (pid {server}) outlived the session"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()


@pytest.mark.parametrize("required", ["", "1"])
def test_without_server_binaries_the_tests_skip_or_with_the_ci_variable_fail(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, required: str
) -> None:
    monkeypatch.setenv("PG_BIN", str(tmp_path / "no-postgres-here"))
    monkeypatch.setenv("RIG_REQUIRE_POSTGRES", required)
    outcome = pytest.fail.Exception if required else pytest.skip.Exception
    with pytest.raises(outcome) as stopped:
        require_bin_dir()
    assert "apt-get install postgresql" in stopped.value.msg
    assert ("RIG_REQUIRE_POSTGRES=1" in stopped.value.msg) == bool(required)
    if required:
        assert stopped.value.pytrace is False  # the failure is reported as one line, no traceback

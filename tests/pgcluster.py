"""A throwaway PostgreSQL cluster for the tests: initdb into a temporary folder, start, stop, delete.

The machines this project is tested on have the server binaries installed (Debian:
/usr/lib/postgresql/VERSION/bin) but no server running. `throwaway_cluster()` makes one:

    with throwaway_cluster() as pg:      # initdb + pg_ctl start on a free port of 127.0.0.1
        url = pg.url(pg.create_db())     # postgresql://rig_test:PW@127.0.0.1:PORT/rig_test_1
        pg.stop(); pg.start()            # the server goes away and comes back: same port, same data

Clients reach it over TCP with a password (scram-sha-256), so a wrong password is refused as it
would be in a lab; the superuser reaches it only through the unix socket in the temporary folder.
The server refuses to run as root, so when the tests run as root the folder belongs to the
`postgres` user and every server command runs as that user (runuser, else su). A watchdog process
stops the server and deletes the folder if the test process dies without doing so itself (kill -9).
fsync is off (the data lives as long as the session); synchronous_commit stays on, so a commit
that returned survives `stop("immediate")`, the way a crashed lab server keeps committed entries.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import shlex
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import quote

import psycopg
from psycopg import sql

INSTALL_HINT = (
    "PostgreSQL server binaries not found (looked in PG_BIN and /usr/lib/postgresql/*/bin); "
    "install them with `apt-get install postgresql` on Debian (the server need not run), "
    "or point PG_BIN at the folder holding initdb and pg_ctl"
)
START_TIMEOUT_S = 180.0  # initdb took 15 s and more on a machine loaded ~5x its cores
SUPERUSER = "rig_super"
LOGIN_ROLE = "rig_test"
_TOOLS = ("initdb", "pg_ctl", "pg_isready")

# Runs beside the test process; when that process is gone (reparented), stops and deletes the cluster.
_WATCHDOG = """
import os, shutil, subprocess, sys, time
parent, stop, folder = int(sys.argv[1]), sys.argv[2:-1], sys.argv[-1]
print("watching", flush=True)
while os.getppid() == parent:
    time.sleep(0.5)
subprocess.run(stop, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False)
shutil.rmtree(folder, ignore_errors=True)
"""


class ClusterError(RuntimeError):
    """The throwaway cluster could not be created, started or stopped (the message says why)."""


def _version_key(path: Path) -> tuple[int, ...]:
    return tuple(int(n) for n in re.findall(r"\d+", path.parent.name)) or (0,)


def find_bin_dir(base: Path = Path("/usr/lib/postgresql")) -> Path | None:
    """The folder of the server binaries: PG_BIN if set, else the newest BASE/VERSION/bin."""
    if env := os.environ.get("PG_BIN"):
        candidates = [Path(env)]
    else:
        candidates = sorted(base.glob("*/bin"), key=_version_key, reverse=True)
    for folder in candidates:
        if all(os.access(folder / tool, os.X_OK) for tool in _TOOLS):
            return folder
    return None


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class PgCluster:
    """A running throwaway cluster: where it listens, the login role, and its life cycle."""

    bin_dir: Path
    root: Path  # the temporary folder: data/, the unix socket, server.log
    port: int
    host: str = "127.0.0.1"
    user: str = LOGIN_ROLE
    password: str = field(default_factory=lambda: secrets.token_hex(16))
    as_postgres: bool = field(default_factory=lambda: os.geteuid() == 0)
    timings: dict[str, float] = field(default_factory=dict)  # seconds: initdb, start (the latest)
    create_times: list[float] = field(default_factory=list)  # seconds, one per create_db()
    stopped: bool = True  # as this object left it: False after start(), True after stop()
    _databases: int = 0
    _watchdog: subprocess.Popen[str] | None = None

    @property
    def data_dir(self) -> Path:
        return self.root / "data"

    @property
    def log_file(self) -> Path:
        return self.root / "server.log"

    def url(self, dbname: str, *, password: str | None = None) -> str:
        """postgresql://USER:PW@127.0.0.1:PORT/DBNAME (another password for testing refusal)."""
        pw = quote(self.password if password is None else password, safe="")
        user, db = quote(self.user, safe=""), quote(dbname, safe="")
        return f"postgresql://{user}:{pw}@{self.host}:{self.port}/{db}"

    # -- life cycle --------------------------------------------------------------------------------

    def _command(self, tool: str, *args: str) -> list[str]:
        cmd = [str(self.bin_dir / tool), *args]
        if not self.as_postgres:
            return cmd
        if runuser := shutil.which("runuser"):
            return [runuser, "-u", "postgres", "--", *cmd]
        return ["su", "postgres", "-s", "/bin/sh", "-c", shlex.join(cmd)]

    def _run(self, tool: str, *args: str, timeout: float = START_TIMEOUT_S) -> None:
        try:
            done = subprocess.run(
                self._command(tool, *args),
                cwd=self.root,  # root's own home may be unreadable to the postgres user
                stdin=subprocess.DEVNULL,
                capture_output=True,
                text=True,
                timeout=timeout,
                check=False,
            )
        except subprocess.TimeoutExpired as exc:
            raise ClusterError(f"{tool} took more than {timeout:.0f} s{self._log_tail()}") from exc
        if done.returncode != 0:
            why = " / ".join((done.stderr or done.stdout).strip().splitlines()[-3:])
            raise ClusterError(f"{tool} failed (exit {done.returncode}): {why}{self._log_tail()}")

    def _log_tail(self) -> str:
        try:
            lines = self.log_file.read_text(errors="replace").strip().splitlines()
        except OSError:
            return ""
        return f"; server log: {' / '.join(lines[-3:])}" if lines else ""

    def init(self) -> None:
        """initdb with password auth over TCP, trust on the private unix socket; write the settings."""
        t0 = time.perf_counter()
        self._run(
            "initdb",
            "-D",
            str(self.data_dir),
            "-U",
            SUPERUSER,
            "--no-locale",
            "-E",
            "UTF8",
            "--auth-local=trust",
            "--auth-host=scram-sha-256",
            "--no-sync",
            "--no-instructions",
        )
        (self.data_dir / "pg_hba.conf").write_text(
            "# throwaway test cluster: the superuser only on the private socket, clients by password\n"
            "local all all trust\n"
            "host all all 127.0.0.1/32 scram-sha-256\n"
        )
        with (self.data_dir / "postgresql.conf").open("a") as conf:
            conf.write(
                "\n# throwaway test cluster\n"
                f"listen_addresses = '{self.host}'\n"
                f"unix_socket_directories = '{self.root}'\n"
                "fsync = off\nfull_page_writes = off\n"
                "max_connections = 200\nshared_buffers = 32MB\n"
            )
        self.timings["initdb"] = time.perf_counter() - t0

    def start(self, timeout: float = START_TIMEOUT_S) -> None:
        """Start the server (same port, same data) and wait until it accepts TCP connections."""
        t0 = time.perf_counter()
        args = ["-D", str(self.data_dir), "-l", str(self.log_file), "-o", f"-p {self.port}"]
        self._run("pg_ctl", "start", *args, "-w", "-t", str(int(timeout)), timeout=timeout + 10)
        deadline = time.monotonic() + timeout
        while True:  # pg_ctl waited for the postmaster; pg_isready confirms the TCP listener
            ready = subprocess.run(
                [str(self.bin_dir / "pg_isready"), "-h", self.host, "-p", str(self.port), "-t", "2"],
                stdin=subprocess.DEVNULL,
                capture_output=True,
                check=False,
            )
            if ready.returncode == 0:
                break
            if time.monotonic() > deadline:
                where = f"{self.host}:{self.port}"
                raise ClusterError(f"server not ready on {where} after {timeout:.0f} s{self._log_tail()}")
            time.sleep(0.1)
        self.stopped = False
        self.timings["start"] = time.perf_counter() - t0

    def stop(self, mode: str = "fast") -> None:
        """Stop the server: "fast" (clean) or "immediate" (as if it crashed; the data survives)."""
        self._run("pg_ctl", "stop", "-D", str(self.data_dir), "-m", mode, "-w")
        self.stopped = True

    @property
    def running(self) -> bool:
        """True when the postmaster of this cluster is alive (its pid file names a live process)."""
        done = subprocess.run(
            self._command("pg_ctl", "status", "-D", str(self.data_dir)),
            cwd=self.root,
            stdin=subprocess.DEVNULL,
            capture_output=True,
            check=False,
        )
        return done.returncode == 0

    def watch(self) -> None:
        """Start the watchdog that cleans up if this process dies without calling destroy()."""
        stop = self._command("pg_ctl", "stop", "-D", str(self.data_dir), "-m", "immediate", "-w")
        self._watchdog = subprocess.Popen(
            [sys.executable, "-c", _WATCHDOG, str(os.getpid()), *stop, str(self.root)],
            cwd=self.root,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
            start_new_session=True,  # a Ctrl-C to the test run must not kill it first
        )
        assert self._watchdog.stdout is not None
        self._watchdog.stdout.readline()

    def destroy(self) -> None:
        """Stop the server (immediately: nothing in it is kept) and delete its folder."""
        if self._watchdog is not None:
            self._watchdog.kill()
            self._watchdog.wait()
            if self._watchdog.stdout is not None:
                self._watchdog.stdout.close()
            self._watchdog = None
        if (self.data_dir / "postmaster.pid").exists():
            with contextlib.suppress(ClusterError):
                self.stop("immediate")
        shutil.rmtree(self.root, ignore_errors=True)

    # -- databases ---------------------------------------------------------------------------------

    def admin(self) -> psycopg.Connection[tuple[object, ...]]:
        """A superuser connection (autocommit) over the private unix socket."""
        return psycopg.connect(
            host=str(self.root),
            port=self.port,
            user=SUPERUSER,
            dbname="postgres",
            autocommit=True,
            connect_timeout=30,
        )

    def create_login_role(self) -> None:
        """The role tests connect as: LOGIN with a password, CREATEDB; it owns every test database."""
        with self.admin() as conn:
            conn.execute(
                sql.SQL("CREATE ROLE {} LOGIN CREATEDB PASSWORD {}").format(
                    sql.Identifier(self.user), sql.Literal(self.password)
                )
            )

    def create_db(self, template: str = "template0") -> str:
        """A fresh, empty database owned by the login role; returns its name."""
        t0 = time.perf_counter()
        self._databases += 1
        name = f"rig_test_{self._databases}"
        with self.admin() as conn:
            conn.execute(
                sql.SQL("CREATE DATABASE {} OWNER {} TEMPLATE {}").format(
                    sql.Identifier(name), sql.Identifier(self.user), sql.Identifier(template)
                )
            )
        self.create_times.append(time.perf_counter() - t0)
        return name

    def drop_db(self, name: str) -> None:
        """Drop a test database, closing whatever connections a test left open to it."""
        with self.admin() as conn:
            conn.execute(sql.SQL("DROP DATABASE IF EXISTS {} WITH (FORCE)").format(sql.Identifier(name)))


def _make_root() -> Path:
    # The unix socket path must stay under ~107 bytes: a long TMPDIR falls back to /tmp.
    base = tempfile.gettempdir()
    root = Path(tempfile.mkdtemp(prefix="rig-pg-", dir=base if len(base) < 60 else "/tmp"))
    if os.geteuid() == 0:
        try:
            shutil.chown(root, user="postgres", group="postgres")
        except (LookupError, OSError) as exc:
            shutil.rmtree(root, ignore_errors=True)
            raise ClusterError(
                "running as root needs a `postgres` user to own the test cluster "
                f"(the server refuses to run as root): {exc}"
            ) from exc
    return root


@contextlib.contextmanager
def throwaway_cluster(bin_dir: Path | None = None) -> Iterator[PgCluster]:
    """A started cluster with the login role made; stopped and deleted when the block ends."""
    bin_dir = bin_dir or find_bin_dir()
    if bin_dir is None:
        raise ClusterError(INSTALL_HINT)
    t0 = time.perf_counter()
    cluster = PgCluster(bin_dir=bin_dir, root=_make_root(), port=_free_port())
    try:
        cluster.watch()
        cluster.init()
        for attempt in range(3):  # another process may take the free port between probe and bind
            try:
                cluster.start()
                break
            except ClusterError as exc:
                if attempt == 2 or "already in use" not in str(exc):
                    raise
                cluster.port = _free_port()
        cluster.create_login_role()
        cluster.timings["up"] = time.perf_counter() - t0
        yield cluster
    finally:
        cluster.destroy()

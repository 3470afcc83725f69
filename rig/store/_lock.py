"""One runner per run: a lock row in the store with an owner token, a host, a pid and a lease.

The lock lives in the database, not in the operating system, so that it works the same when the
records move to a database shared by several machines. It is taken and checked inside the store's
write transactions (BEGIN IMMEDIATE), so two runners can never both hold it.

A lock is stale, and may be broken by the next runner, when
- it was taken on this host and its process no longer exists, or
- its lease ran out: the holder's heartbeat did not renew it for `lease_s` seconds.
"""

from __future__ import annotations

import os
import socket
import sqlite3
import threading
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timedelta

from rig.core.errors import StoreError

COLUMNS = "run_id, owner, host, pid, since_utc, heartbeat_utc, lease_s"


class RunLocked(StoreError):
    """Another runner holds the run (the message names its host, pid and since when)."""


@dataclass(frozen=True)
class RunLock:
    """One row of `run_locks`: who runs a run, since when, and the lease's last renewal."""

    run_id: str
    owner: str
    host: str
    pid: int
    since_utc: str
    heartbeat_utc: str
    lease_s: float

    @property
    def expires(self) -> datetime:
        """When the lease runs out unless the holder's heartbeat renews it."""
        return datetime.fromisoformat(self.heartbeat_utc) + timedelta(seconds=self.lease_s)

    def describe(self) -> str:
        """'host H pid P since T' for messages and the log."""
        return f"host {self.host} pid {self.pid} since {self.since_utc}"

    def as_payload(self) -> dict[str, object]:
        """The holder as a log payload (the owner token is a secret of the holder: left out)."""
        return {
            "host": self.host,
            "pid": self.pid,
            "since_utc": self.since_utc,
            "heartbeat_utc": self.heartbeat_utc,
            "lease_s": self.lease_s,
        }


def this_host() -> str:
    """The name this machine gives itself (compared to a lock's host to decide on the pid check)."""
    return socket.gethostname()


def read(conn: sqlite3.Connection, run_id: str) -> RunLock | None:
    """The run's lock row, if any."""
    row = conn.execute(f"SELECT {COLUMNS} FROM run_locks WHERE run_id = ?", (run_id,)).fetchone()
    return RunLock(*row) if row else None


def stale_reason(lock: RunLock, now: datetime) -> str | None:
    """Why `lock` may be broken, or None while its holder may still be running."""
    if lock.host == this_host() and not _pid_alive(lock.pid):
        return f"process {lock.pid} no longer runs on {lock.host}"
    if now >= lock.expires:
        return f"its lease expired at {lock.expires.isoformat(timespec='seconds')} (no heartbeat since)"
    return None


def refusal(run_id: str, lock: RunLock) -> str:
    """The message for a second runner."""
    expiry = lock.expires.isoformat(timespec="seconds")
    return (
        f"run {run_id} is already being run by {lock.describe()} (last heartbeat {lock.heartbeat_utc}); "
        f"only one runner at a time: wait for it to end (if it was killed on another machine, "
        f"its lease runs out at {expiry})"
    )


def insert(conn: sqlite3.Connection, lock: RunLock) -> None:
    """Write the lock row (caller holds the write transaction and has removed any stale one)."""
    conn.execute(
        f"INSERT INTO run_locks ({COLUMNS}) VALUES (?, ?, ?, ?, ?, ?, ?)",
        (lock.run_id, lock.owner, lock.host, lock.pid, lock.since_utc, lock.heartbeat_utc, lock.lease_s),
    )


def remove(conn: sqlite3.Connection, run_id: str, owner: str) -> None:
    """Delete the run's lock row if `owner` holds it."""
    conn.execute("DELETE FROM run_locks WHERE run_id = ? AND owner = ?", (run_id, owner))


def renew(conn: sqlite3.Connection, run_id: str, owner: str, now_utc: str) -> bool:
    """Move the lease on; False if `owner` no longer holds the lock (it was broken)."""
    cur = conn.execute(
        "UPDATE run_locks SET heartbeat_utc = ? WHERE run_id = ? AND owner = ?", (now_utc, run_id, owner)
    )
    return cur.rowcount == 1


def _pid_alive(pid: int) -> bool:
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    except OSError:
        return False
    return not _is_zombie(pid)


def _is_zombie(pid: int) -> bool:
    """A process that has ended but not been reaped by its parent (Linux: state Z in /proc)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except (OSError, IndexError):
        return False


class Heartbeat(threading.Thread):
    """Calls `renew` every `interval_s` until stopped or `renew` says the lock is gone (False)."""

    def __init__(self, renew: Callable[[], bool], name: str, interval_s: float) -> None:
        super().__init__(name=name, daemon=True)
        self._renew, self._interval_s = renew, interval_s
        self._stopped = threading.Event()

    def run(self) -> None:
        """Renew at each beat; a broken lock ends the beat, a busy or closed store only skips one."""
        while not self._stopped.wait(self._interval_s):
            try:
                if not self._renew():
                    return  # broken: the store refuses this runner's next append
            except StoreError:
                continue  # busy or closed: try again at the next beat

    def stop(self) -> None:
        """Stop beating and wait for the thread to end."""
        self._stopped.set()
        if self.is_alive():
            self.join()

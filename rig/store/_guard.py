"""The store's files as a writer opened them: each write first checks they are still those files.

SQLite keeps writing to a file that was deleted (the open descriptor outlives the name) and does
not notice one truncated under it: a run would go on recording into nothing and print a verdict
that no store holds. The writer therefore checks, before and after every write transaction, that
NAME, NAME-wal and NAME-shm are the files it opened (same device and inode) and that NAME has not
shrunk (the log is append-only and the file is never vacuumed). A few stat calls per write; damage
inside the file is found by Store.check_integrity and the check of a sealed run (Store.confirm_sealed).
"""

from __future__ import annotations

import os
from pathlib import Path

from rig.core.errors import StoreError

_SUFFIXES = ("", "-wal", "-shm")


class StoreGone(StoreError):
    """The store's files were deleted, replaced or truncated while it was open for writing."""


class FileGuard:
    """Remembers which files a store's writer opened; `check()` raises StoreGone if they changed."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._ids: dict[str, tuple[int, int]] = {}
        self._size = 0
        self.check()

    def check(self) -> None:
        """Raise StoreGone naming the first file that is gone, replaced or cut short."""
        for suffix in _SUFFIXES:
            name = self.path.name + suffix
            try:
                st = os.stat(self.path.with_name(name))
            except FileNotFoundError:
                if suffix == "" or suffix in self._ids:
                    self._gone(f"{name} is gone")
                continue  # SQLite makes it at the first read or write
            except OSError as exc:
                self._gone(f"{name} cannot be read: {exc.strerror or exc}")
            if self._ids.setdefault(suffix, (st.st_dev, st.st_ino)) != (st.st_dev, st.st_ino):
                self._gone(f"{name} was replaced")
            if suffix == "":
                self._check_main(name, st.st_size)

    def _check_main(self, name: str, size: int) -> None:
        # stat only: opening and closing the file here would drop SQLite's POSIX locks on it (all of
        # a process's locks on a file go with any of its descriptors), letting another process
        # delete the WAL under this connection
        if size < self._size:
            self._gone(f"{name} was truncated from {self._size} to {size} bytes")
        self._size = size

    def _gone(self, what: str) -> None:
        raise StoreGone(
            f"{self.path}: the store's files changed while it was open ({what}); nothing more is "
            "written to them"
        )

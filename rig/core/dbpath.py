"""Where the record store is when a command names none: $RIG_DB, else rig-records.db here."""

from __future__ import annotations

import os
from pathlib import Path

DB_ENV = "RIG_DB"
DEFAULT_DB_NAME = "rig-records.db"
DB_HELP = f"record store: a file or a postgresql:// URL (default ${DB_ENV}, else {DEFAULT_DB_NAME} here)"


def default_db() -> Path | str:
    """$RIG_DB if set (a file, or a database URL kept as text), else rig-records.db in the
    working directory."""
    named = os.environ.get(DB_ENV, "").strip()
    if not named:
        return Path(DEFAULT_DB_NAME)
    return named if "://" in named else Path(named).expanduser()

"""SQL views for analysts over the log: `shots` and `runs_summary`, for SQLite and PostgreSQL.

A view is schema, not data: nothing in it is hashed, and it is rebuilt from the log on every
query. Both engines get the same view from one builder, so the two texts cannot drift apart;
only how a JSON value is read differs (json_extract on SQLite, (payload::jsonb)->>'key' on
PostgreSQL). Like a certificate, a view shows a run only up to its seal (its first closing
RunStatusChanged): an entry appended to a closed run behind the store's back is left out.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

from rig.core.errors import UnknownRecord

ColumnType = Literal["text", "int", "float", "bool"]

# Column names and types, in view order; `rig export` types its columns from these.
VIEW_COLUMNS: dict[str, tuple[tuple[str, ColumnType], ...]] = {
    "shots": (
        ("run_id", "text"),
        ("rig", "text"),
        ("bat_id", "text"),
        ("shot_index", "int"),
        ("purpose", "text"),
        ("location_in", "float"),
        ("inbound_speed_m_s", "float"),
        ("rebound_speed_m_s", "float"),
        ("metric", "float"),
        ("u", "float"),
        ("valid", "bool"),
        ("reasons", "text"),
        ("t_utc", "text"),
    ),
    "runs_summary": (
        ("run_id", "text"),
        ("rig", "text"),
        ("bat_id", "text"),
        ("procedure", "text"),
        ("status", "text"),
        ("verdict", "text"),
        ("mean", "float"),
        ("expanded_uncertainty", "float"),
        ("k", "float"),
        ("started_utc", "text"),
        ("finished_utc", "text"),
    ),
}
VIEWS = tuple(VIEW_COLUMNS)
_ORDER = {"shots": "t_utc, run_id, shot_index", "runs_summary": "started_utc, run_id"}
_SHOT_KINDS = "'ShotRequested', 'ShotFired', 'ShotMeasured', 'ShotRejected', 'ShotLost', 'ShotOverruled'"


@dataclass(frozen=True)
class _Dialect:
    """How one engine reads a JSON payload: text at a path, a number, an integer, reason codes."""

    text: Callable[[str, str], str]  # (table alias, dotted path) -> SQL text expression
    number: Callable[[str, str], str]
    integer: Callable[[str, str], str]
    codes: Callable[[str], str]  # (alias) -> the 'code' of each item of payload.reasons, joined by ','
    join: str  # the string aggregate: group_concat or string_agg


def _pg_text(alias: str, path: str) -> str:
    keys = path.split(".")
    if len(keys) == 1:
        return f"(({alias}.payload::jsonb)->>'{path}')"
    return f"(({alias}.payload::jsonb)#>>'{{{','.join(keys)}}}')"


SQLITE = _Dialect(
    text=lambda a, p: f"json_extract({a}.payload, '$.{p}')",
    number=lambda a, p: f"json_extract({a}.payload, '$.{p}')",
    integer=lambda a, p: f"json_extract({a}.payload, '$.{p}')",
    # an old log might hold a reason as a bare string: json_extract on it would fail the whole view
    codes=lambda a: (
        "(SELECT group_concat(CASE r.type WHEN 'object' THEN json_extract(r.value, '$.code') "
        f"ELSE r.value END, ',') FROM json_each({a}.payload, '$.reasons') AS r)"
    ),
    join="group_concat",
)
POSTGRES = _Dialect(
    text=_pg_text,
    number=lambda a, p: f"{_pg_text(a, p)}::double precision",
    integer=lambda a, p: f"{_pg_text(a, p)}::integer",
    codes=lambda a: (
        "(SELECT string_agg(coalesce(r.item->>'code', r.item#>>'{}'), ',' ORDER BY r.n) "
        f"FROM jsonb_array_elements(CASE jsonb_typeof(({a}.payload::jsonb)->'reasons') "
        f"WHEN 'array' THEN ({a}.payload::jsonb)->'reasons' END) WITH ORDINALITY AS r(item, n))"
    ),
    join="string_agg",
)


def _seals(d: _Dialect) -> str:
    # a run's seal: its first status change to a closed status; nothing of the run may follow it
    return f"""seals AS (
    SELECT run_id, min(seq) AS seal_seq FROM log
    WHERE kind = 'RunStatusChanged' AND {d.text("log", "status")} IN ('finished', 'aborted')
    GROUP BY run_id)"""


def shots_sql(d: _Dialect) -> str:
    """CREATE VIEW shots: one row per ShotFired entry, with its request and latest outcome."""
    return f"""CREATE VIEW shots AS
WITH {_seals(d)},
shot_entries AS (
    SELECT log.seq, log.run_id, log.kind, {d.integer("log", "index")} AS shot_index
    FROM log LEFT JOIN seals ON seals.run_id = log.run_id
    WHERE log.kind IN ({_SHOT_KINDS})
      AND (seals.seal_seq IS NULL OR log.seq < seals.seal_seq)),
per_shot AS (
    SELECT run_id, shot_index,
        max(seq) FILTER (WHERE kind = 'ShotRequested') AS requested_seq,
        max(seq) FILTER (WHERE kind IN ('ShotMeasured', 'ShotRejected')) AS outcome_seq,
        max(seq) FILTER (WHERE kind = 'ShotLost') AS lost_seq,
        {d.join}('OPERATOR_REJECTED', ',') FILTER (WHERE kind = 'ShotOverruled') AS overrules
    FROM shot_entries GROUP BY run_id, shot_index),
created AS MATERIALIZED (  -- joined by run: a lookup by kind per shot would scan every run
    SELECT run_id, seq FROM log WHERE kind = 'RunCreated')
SELECT
    f.run_id AS run_id,
    {d.text("c", "meta.rig.name")} AS rig,
    {d.text("c", "bat_id")} AS bat_id,
    f.shot_index AS shot_index,
    {d.text("q", "purpose")} AS purpose,
    {d.number("q", "location_in")} AS location_in,
    {d.number("o", "inbound_speed_m_s")} AS inbound_speed_m_s,
    {d.number("o", "rebound_speed_m_s")} AS rebound_speed_m_s,
    {d.number("o", "metric")} AS metric,
    {d.number("o", "u")} AS u,
    CASE WHEN p.lost_seq IS NOT NULL OR p.overrules IS NOT NULL THEN 0
         WHEN o.kind = 'ShotMeasured' THEN 1
         WHEN o.kind = 'ShotRejected' THEN 0 END AS valid,
    CASE WHEN p.lost_seq IS NOT NULL THEN 'LOST'
         ELSE ltrim(coalesce({d.codes("o")}, '') || coalesce(',' || p.overrules, ''), ',') END AS reasons,
    fl.t_utc AS t_utc
FROM shot_entries AS f
JOIN log AS fl ON fl.seq = f.seq
JOIN per_shot AS p ON p.run_id = f.run_id AND p.shot_index = f.shot_index
LEFT JOIN created ON created.run_id = f.run_id
LEFT JOIN log AS c ON c.seq = created.seq
LEFT JOIN log AS q ON q.seq = p.requested_seq
LEFT JOIN log AS o ON o.seq = p.outcome_seq
WHERE f.kind = 'ShotFired'"""


def runs_summary_sql(d: _Dialect) -> str:
    """CREATE VIEW runs_summary: one row per RunCreated, with its status, verdict and mean +- U."""
    return f"""CREATE VIEW runs_summary AS
WITH {_seals(d)},
closing AS (
    SELECT log.run_id,
        max(log.seq) FILTER (WHERE log.kind = 'RunStatusChanged') AS status_seq,
        max(log.seq) FILTER (WHERE log.kind = 'RunFinished') AS finished_seq
    FROM log LEFT JOIN seals ON seals.run_id = log.run_id
    WHERE log.kind IN ('RunStatusChanged', 'RunFinished')
      AND (seals.seal_seq IS NULL OR log.seq <= seals.seal_seq)
    GROUP BY log.run_id)
SELECT
    c.run_id AS run_id,
    {d.text("c", "meta.rig.name")} AS rig,
    {d.text("c", "bat_id")} AS bat_id,
    {d.text("c", "procedure")} AS procedure,
    coalesce({d.text("s", "status")}, 'running') AS status,
    coalesce({d.text("f", "verdict")}, {d.text("s", "verdict")}) AS verdict,
    {d.number("f", "mean")} AS mean,
    {d.number("f", "U")} AS expanded_uncertainty,
    {d.number("f", "coverage_k")} AS k,
    c.t_utc AS started_utc,
    CASE WHEN {d.text("s", "status")} IN ('finished', 'aborted') THEN s.t_utc END AS finished_utc
FROM log AS c
LEFT JOIN closing AS x ON x.run_id = c.run_id
LEFT JOIN log AS s ON s.seq = x.status_seq
LEFT JOIN log AS f ON f.seq = x.finished_seq
WHERE c.kind = 'RunCreated'"""


SQLITE_VIEWS: tuple[str, ...] = (shots_sql(SQLITE), runs_summary_sql(SQLITE))
"""The views on SQLite (schema version 3 adds them)."""
POSTGRES_VIEWS: tuple[str, ...] = (shots_sql(POSTGRES), runs_summary_sql(POSTGRES))
"""The same views on PostgreSQL, over a `log` table with the same columns (payload as text or jsonb)."""


def view_query(view: str, run_id: str | None = None, placeholder: str = "?") -> tuple[str, tuple[Any, ...]]:
    """The SELECT (and its parameters) reading a view in a stable order, of one run or all.

    `placeholder` is the driver's parameter mark: '?' for sqlite3, '%s' for psycopg.
    """
    if view not in VIEW_COLUMNS:
        raise UnknownRecord(f"no view {view!r}; the views are {', '.join(VIEWS)}")
    columns = ", ".join(name for name, _ in VIEW_COLUMNS[view])
    where, params = (f"WHERE run_id = {placeholder}", (run_id,)) if run_id is not None else ("", ())
    return f"SELECT {columns} FROM {view} {where} ORDER BY {_ORDER[view]}", params


def read_view(conn: sqlite3.Connection, view: str, run_id: str | None = None) -> list[dict[str, Any]]:
    """A view's rows as dicts with Python types (floats as float, valid as bool, NULL as None)."""
    sql, params = view_query(view, run_id)
    columns = VIEW_COLUMNS[view]
    return [
        {name: _typed(kind, value) for (name, kind), value in zip(columns, row, strict=True)}
        for row in conn.execute(sql, params)
    ]


def _typed(kind: ColumnType, value: Any) -> Any:
    if value is None:
        return None
    if kind == "float":
        return float(value)
    if kind == "int":
        return int(value)
    if kind == "bool":
        return bool(value)
    return str(value)

"""Benchmark: four rigs certifying at once into one store, PostgreSQL and SQLite (issue 12).

Four processes each run a full simulated certification (ideal scene, BBCOR) into one PostgreSQL
database (a throwaway cluster, as the tests start it) and then into one SQLite file. Each times
every append it makes; afterwards the store is read back: entries per second, append latency
(median, p99, max), entries lost (what each process appended and was told was committed, against
what the store holds), and the chains verified. Then one certification alone on each engine.

Targets: p99 append on PostgreSQL <= 20 ms; a certification on PostgreSQL within 2x its SQLite
time. Run with `make bench` (skipped, saying so, where the PostgreSQL binaries are missing).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"


def _one_rig(where: str, name: str, out: Any) -> None:
    """A rig process: one certification, every append timed; reports its run, latencies, seqs."""
    sys.path.insert(0, str(ROOT))
    import faulthandler

    faulthandler.dump_traceback_later(90, exit=True)  # a rig stuck for 90 s shows where, then ends
    from rig.certification import certify
    from rig.core.bat import BatSpec
    from rig.protocols.procedure import Procedure
    from rig.session import sim_config
    from rig.store import Store

    latencies: list[float] = []
    committed: list[int] = []
    original = Store.append_many

    def timed(self: Store, items: Any) -> Any:
        t0 = time.perf_counter()
        entries = original(self, items)
        latencies.append(time.perf_counter() - t0)
        committed.extend(e.seq for e in entries)
        return entries

    Store.append_many = timed  # type: ignore[method-assign]
    bat = BatSpec.load(BAT)
    with Store.open(where) as store:
        t0 = time.perf_counter()
        result = certify(store, Procedure.load("bbcor"), bat, sim_config("ideal", bat=bat))
        wall = time.perf_counter() - t0
    out.put(
        {
            "rig": name,
            "run": result.run_id,
            "status": result.status,
            "wall": wall,
            "latencies": latencies,
            "committed": committed,
        }
    )


def _burn() -> None:
    """A CPU-bound process (the machine busy, as CI machines are)."""
    while True:
        sum(i * i for i in range(100_000))


def concurrent(where: str, rigs: int) -> dict[str, Any]:
    """`rigs` processes certifying into `where` at once."""
    from rig.store import Store

    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    Store.open(where).close()  # the schema made once, before the rigs start
    procs = [ctx.Process(target=_one_rig, args=(where, f"rig-{k}", queue)) for k in range(rigs)]
    t0 = time.perf_counter()
    for p in procs:
        p.start()
    results = [queue.get(timeout=150) for _ in procs]
    for p in procs:
        p.join(60)
    wall = time.perf_counter() - t0
    failed = [f"{r['rig']}: {r['error']}" for r in results if "error" in r]
    if failed:
        raise SystemExit(f"bench_lab_store: a rig failed: {'; '.join(failed)}")
    with Store.open(where, create=False) as store:
        report = store.verify()
        held = {e.seq for e in store.entries()}
        appended = sum(len(r["committed"]) for r in results)
        lost = sum(1 for r in results for seq in r["committed"] if seq not in held)
        statuses = [store.run(r["run"]).status for r in results]
    lat = sorted(x for r in results for x in r["latencies"])
    return {
        "rigs": rigs,
        "wall_s": wall,
        "appended": appended,
        "entries_per_s": appended / wall,
        "p50_ms": 1e3 * statistics.median(lat),
        "p99_ms": 1e3 * lat[min(len(lat) - 1, int(0.99 * len(lat)))],
        "max_ms": 1e3 * lat[-1],
        "lost": lost,
        "verified": report.ok,
        "finished": statuses.count("finished"),
    }


def alone(where: str) -> float:
    """Wall time of one certification into `where` (the store already made)."""
    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    p = ctx.Process(target=_one_rig, args=(where, "alone", queue))
    p.start()
    got = queue.get(timeout=150)
    p.join(60)
    if "error" in got:
        raise SystemExit(f"bench_lab_store: {got['error']}")
    return float(got["wall"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rigs", type=int, default=4)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--load", type=int, default=0, help="CPU-bound processes to run beside it")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from tests.pgcluster import find_bin_dir, throwaway_cluster

    if find_bin_dir() is None:
        print("bench_lab_store: no PostgreSQL server binaries (apt-get install postgresql): skipped")
        return 0
    rows: dict[str, dict[str, Any]] = {}
    burners = [
        multiprocessing.get_context("spawn").Process(target=_burn, daemon=True) for _ in range(args.load)
    ]
    for b in burners:
        b.start()
    with throwaway_cluster() as cluster, tempfile.TemporaryDirectory() as tmp:
        rows["postgresql"] = concurrent(cluster.url(cluster.create_db()), args.rigs)
        rows["sqlite"] = concurrent(str(Path(tmp) / "lab.db"), args.rigs)
        pg_url = cluster.url(cluster.create_db())
        sqlite_path = str(Path(tmp) / "alone.db")
        for where in (pg_url, sqlite_path):
            from rig.store import Store

            Store.open(where).close()
        t_pg = min(alone(pg_url) for _ in range(2))
        t_sqlite = min(alone(sqlite_path) for _ in range(2))
    for b in burners:
        b.terminate()
    if args.load:
        print(f"with {args.load} CPU-bound processes beside it")
    if args.json:
        print(json.dumps({"concurrent": rows, "alone_s": {"postgresql": t_pg, "sqlite": t_sqlite}}, indent=2))
    for engine, r in rows.items():
        print(
            f"{engine:<10} {r['rigs']} rigs at once: {r['appended']} entries in {r['wall_s']:.2f} s "
            f"({r['entries_per_s']:.0f}/s); append p50 {r['p50_ms']:.2f} ms, p99 {r['p99_ms']:.2f} ms, "
            f"max {r['max_ms']:.1f} ms; lost {r['lost']}; chains verified: {r['verified']}; "
            f"{r['finished']}/{r['rigs']} runs finished"
        )
    ratio = t_pg / t_sqlite
    print(f"one certification alone: PostgreSQL {t_pg:.3f} s, SQLite {t_sqlite:.3f} s, ratio {ratio:.2f}")
    pg = rows["postgresql"]
    targets = [
        ("PostgreSQL append p99 <= 20 ms", pg["p99_ms"] <= 20.0),
        (
            "nothing lost, chains verified (both)",
            all(r["lost"] == 0 and r["verified"] for r in rows.values()),
        ),
        ("certification on PostgreSQL <= 2x SQLite", ratio <= 2.0),
    ]
    for name, ok in targets:
        print(f"target {name:<42} {'met' if ok else 'NOT MET'}")
    return 0 if all(ok for _, ok in targets) else 1


if __name__ == "__main__":
    raise SystemExit(main())

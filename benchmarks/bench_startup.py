"""Benchmark: how long the commands take to start, as ratios to B on the same machine in the same run.

B is the wall time of a fresh `python -c "import numpy, scipy.integrate"` (best of N). Targets
(issue 14): `rig runs` <= 0.3 B, `rig model cor` <= 1.0 B, `rig report RUN --format md` to stdout
<= 1.0 B, the console's first paint <= 1.2 B. Each command is a fresh subprocess, best of N, on a
store prepared once in a temporary folder by a simulated certification. The runs go in rounds (B,
then each command) so that B and the commands see the same load of a shared machine. They run with
bytecode caching on (PYTHONDONTWRITEBYTECODE removed), as on an installed system, after one
untimed warm-up each that writes the bytecode. Run with `make bench` or
`python benchmarks/bench_startup.py [--repeats N] [--json] [--strict]`.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks.bench_startup_console
from benchmarks.bench_startup_console import CONSOLE
from rig.progress import steps

ROOT = Path(__file__).resolve().parents[1]
BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
TARGETS = {
    "rig runs": 0.3,
    "rig model cor": 1.0,
    "rig report RUN --format md": 1.0,
    "console first paint": 1.2,
}

# The child for the console's first paint: `rig tui --sim` through the command line, headless,
# printing 'ready' once the set-up screen has been drawn (benchmarks/bench_startup_console.py).
FIRST_PAINT = CONSOLE


def child_env() -> dict[str, str]:
    """This checkout importable, bytecode cached as on an installed system, no RIG_DB."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONDONTWRITEBYTECODE", "RIG_DB")}
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def wall(argv: list[str], cwd: Path, until: str | None = None) -> float:
    """Seconds from spawning `argv` to its exit (or to the line `until` on its stdout)."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        argv, cwd=cwd, env=child_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    if until is None:
        _, err = proc.communicate(timeout=300)
        seconds = time.perf_counter() - t0
        if proc.returncode not in (0, 1):
            raise RuntimeError(f"{' '.join(argv[2:])} exited {proc.returncode}: {err.strip()[-300:]}")
        return seconds
    assert proc.stdout is not None
    for line in proc.stdout:
        if line.strip() == until:
            seconds = time.perf_counter() - t0
            proc.communicate(timeout=120)
            return seconds
    raise RuntimeError(
        f"{' '.join(argv[2:])} never printed {until!r}: {proc.communicate()[1].strip()[-300:]}"
    )


def first_paint_seconds(db: Path, cwd: Path) -> float:
    """The console's first paint, once: `rig tui --sim` through the command line, headless, in a
    fresh process, until its set-up screen has been drawn once (a hook after its first refresh)."""
    return wall([sys.executable, "-c", FIRST_PAINT, str(db)], cwd, until="ready")


def _failed() -> float:
    """A command that failed once is not run again (nan: not measured)."""
    return float("nan")


def prepare_store(folder: Path) -> tuple[Path, str]:
    """A store holding one simulated BBCOR certification of the sample bat; its run id."""
    from rig.certification import certify
    from rig.core.bat import BatSpec
    from rig.protocols.procedure import Procedure
    from rig.session import sim_config
    from rig.store import Store

    db = folder / "records.db"
    bat = BatSpec.load(BAT)
    with Store.open(db) as store:
        outcome = certify(store, Procedure.load("bbcor"), bat, sim_config("ideal", bat=bat))
    return db, outcome.run_id


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed runs of each command (best counts)")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    parser.add_argument("--strict", action="store_true", help="exit 1 if a target is not met")
    args = parser.parse_args()
    rig = [sys.executable, "-m", "rig.cli"]
    with tempfile.TemporaryDirectory(prefix="rig-bench-startup-") as tmp:
        folder = Path(tmp)
        db, run_id = prepare_store(folder)
        commands = {
            "rig runs": [*rig, "runs", "--db", str(db)],
            "rig model cor": [*rig, "model", "cor", "--speed", "60.8", "--hoop", "1276"],
            "rig report RUN --format md": [*rig, "report", run_id[:12], "--db", str(db), "--format", "md"],
        }
        runs: dict[str, Callable[[], float]] = {
            "B": lambda: wall([sys.executable, "-c", "import numpy, scipy.integrate"], folder),
            **{name: functools.partial(wall, argv, folder) for name, argv in commands.items()},
            "console first paint": lambda: first_paint_seconds(db, folder),
        }
        seconds: dict[str, float | None] = {name: None for name in runs}
        with steps(len(runs) * (args.repeats + 1), "start-up") as bar:
            for round_ in range(args.repeats + 1):  # round 0 is the warm-up: writes the bytecode
                for name, run in runs.items():
                    bar.note(f"round {round_}/{args.repeats}: {name}")
                    try:
                        t = run()
                    except (RuntimeError, subprocess.TimeoutExpired) as exc:
                        print(f"{name} not measured: {exc}", file=sys.stderr)
                        runs[name] = _failed
                        t = None
                    bar.advance()
                    if round_ and t is not None and t == t:
                        best = seconds[name]
                        seconds[name] = t if best is None else min(best, t)
        b = seconds.pop("B")
        if b is None:
            raise SystemExit("bench_startup: the baseline (import numpy, scipy.integrate) failed")
        left = sorted(p.name for p in folder.iterdir())
    results = [
        {
            "command": name,
            "seconds": s,
            "ratio_to_B": None if s is None else s / b,
            "target_ratio": TARGETS[name],
            "met": None if s is None else s / b <= TARGETS[name],
        }
        for name, s in seconds.items()
    ]
    if args.json:
        print(json.dumps({"B_seconds": b, "repeats": args.repeats, "results": results}, indent=2))
    else:
        print(f"B = import numpy, scipy.integrate in a fresh python, best of {args.repeats}: {b:.3f} s")
        width = max(len(str(r["command"])) for r in results)
        for r in results:
            if r["seconds"] is None:
                print(f"{r['command']:<{width}}  not measured         target <= {r['target_ratio']:.1f} B")
                continue
            verdict = "met" if r["met"] else "NOT MET"
            print(
                f"{r['command']:<{width}}  {r['seconds']:.3f} s = {r['ratio_to_B']:.2f} B"
                f"  target <= {r['target_ratio']:.1f} B  {verdict}"
            )
        print(f"files left beside the store by the commands: {', '.join(left)}")
    missed = [r for r in results if r["met"] is False]
    return 1 if args.strict and missed else 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Benchmark: how long a served simulator takes to answer FIRE, first shot and later ones.

Starts the simulated lab rig out of process on TCP ports, as `rig sim serve --scene lab --kind tcp`
does, and fires shots at the byte level (CLAMP, gates ARM, PSET and READY, ARM, FIRE). Reported per
server: the wall time until it announced its ports, the FIRE reply latency of the first shot (FIRE
written -> its reply read) and the median of the later ones. Each server runs idle and then with two
CPU-bound processes beside it (tests/load.py). Servers:
- `rig sim serve`: the product, which warms the physics before announcing its ports;
- `serve --no-warm`: the same server without the warm-up (how it was before), for comparison.
The devices promise a reply within 100 ms (docs/devices/README.md); the controller waits 1 s.
Run: .venv/bin/python benchmarks/bench_serve.py [--shots N --repeat R --only NAME]
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

import serial

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # tests.load, the shared load harness

from rig.drivers.cannon.codec import SPECS as CANNON  # noqa: E402
from rig.drivers.clamp.codec import SPECS as CLAMP  # noqa: E402
from rig.drivers.codec import HostCodec  # noqa: E402
from rig.drivers.gates.codec import SPECS as GATES  # noqa: E402
from rig.drivers.wire import Event, Reply  # noqa: E402
from tests.load import cpu_load  # noqa: E402

SERVERS = {
    "rig sim serve": [sys.executable, "-m", "rig.cli", "sim", "serve", "--scene", "lab", "--kind", "tcp"],
    "serve --no-warm": [
        sys.executable,
        "-m",
        "rig.simulators.serve",
        "--scene",
        "lab",
        "--kind",
        "tcp",
        "--no-warm",
    ],
}
WAIT_S = 30.0
PROMISE_MS = 100.0  # every reply within 100 ms (docs/devices/README.md)


class Dev:
    """One device over a TCP port: commands out, replies and events back, FIRE timed."""

    def __init__(self, url: str, specs: dict) -> None:
        self.port = serial.serial_for_url(url, timeout=WAIT_S)
        self.codec = HostCodec(specs)
        self.events: list[Event] = []

    def ask(self, verb: str, *args: object) -> float:
        """Send one command; wait for its reply; return the seconds it took."""
        seq, frame = self.codec.command(verb, *args)
        t0 = time.perf_counter()
        self.port.write(frame)
        while True:
            line = self.port.read_until(b"\n")
            if not line:
                raise TimeoutError(f"no reply to {verb} within {WAIT_S} s")
            for item in self.codec.feed(line):
                if isinstance(item, Reply) and item.seq == seq:
                    return time.perf_counter() - t0
                if isinstance(item, Event):
                    self.events.append(item)

    def wait(self, name: str, count: int = 1) -> None:
        """Read until `count` events called `name` have come (keeping none)."""
        while sum(e.name == name for e in self.events) < count:
            line = self.port.read_until(b"\n")
            if not line:
                raise TimeoutError(f"no {name} event within {WAIT_S} s")
            self.events += [i for i in self.codec.feed(line) if isinstance(i, Event)]
        self.events = [e for e in self.events if e.name != name]


def measure(argv: list[str], shots: int) -> tuple[float, list[float]]:
    """(seconds to the ports' announcement, FIRE reply latency of each shot) for one server."""
    t0 = time.perf_counter()
    server = subprocess.Popen(argv, cwd=ROOT, stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert server.stdout is not None
        urls = dict(server.stdout.readline().split() for _ in range(3))
        started = time.perf_counter() - t0
        cannon, gates, clamp = (
            Dev(urls["cannon"], CANNON),
            Dev(urls["gates"], GATES),
            Dev(urls["clamp"], CLAMP),
        )
        clamp.ask("CLAMP")
        clamp.wait("LOCK")
        fire: list[float] = []
        for _ in range(shots):
            gates.ask("ARM")
            cannon.ask("PSET", 395.0)
            cannon.wait("READY")
            cannon.ask("ARM")
            fire.append(cannon.ask("FIRE"))
            gates.wait("G", 6)
        return started, fire
    finally:
        os.killpg(server.pid, signal.SIGINT)
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--shots", type=int, default=5, help="shots per server start")
    parser.add_argument("--repeat", type=int, default=3, help="server starts per row")
    parser.add_argument("--only", choices=sorted(SERVERS), help="measure this server only")
    args = parser.parse_args()
    names = [args.only] if args.only else list(SERVERS)
    measure(SERVERS[names[0]], 1)  # a fresh checkout compiles the kernel once; not counted
    print(f"FIRE reply latency of a served lab scene (ms); {args.repeat} starts x {args.shots} shots per row")
    print(f"{'server':<17} {'load':<10} {'start s':>8} {'first FIRE':>18} {'later FIRE (median)':>20}")
    worst_warm = 0.0
    for load in ("idle", "2 burners"):
        for name in names:
            starts, firsts, later = [], [], []
            for _ in range(args.repeat):
                if load == "idle":
                    started, fire = measure(SERVERS[name], args.shots)
                else:
                    with cpu_load():
                        started, fire = measure(SERVERS[name], args.shots)
                starts.append(started)
                firsts.append(fire[0] * 1e3)
                later += [f * 1e3 for f in fire[1:]]
            if name == "rig sim serve":
                worst_warm = max(worst_warm, *firsts)
            first = f"{statistics.median(firsts):.1f} (max {max(firsts):.0f})"
            rest = f"{statistics.median(later):.1f}" if later else "-"
            print(f"{name:<17} {load:<10} {statistics.median(starts):>8.2f} {first:>18} {rest:>20}")
    if "rig sim serve" in names:
        ok = worst_warm < PROMISE_MS
        verdict = "met" if ok else "MISSED"
        print(f"rig sim serve: slowest first FIRE {worst_warm:.0f} ms; promise {PROMISE_MS:.0f} ms {verdict}")
        return 0 if ok else 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

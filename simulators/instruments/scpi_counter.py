"""A simulated SCPI universal counter (53230A class) on a raw TCP port, timing the world's gates.

Line based ("\\n"), one client at a time (a new connection is a replug: the instrument keeps its
state). The three screens are wired OR-ed into channel 1 (rig.drivers.scpi.counter_codec); every
beam break of the world's shots is stamped while a measurement is running. FETC? waits in virtual
time: the world's clock moves to the last expected edge, or to the counter's own measurement timeout
when edges are missing (their places then read 9.91E37).
"""

from __future__ import annotations

import contextlib
import random
from collections import deque
from dataclasses import dataclass
from typing import Any, ClassVar

from rig.drivers.scpi import counter_codec as codec
from rig.simulators.effects.timing import GateTiming
from rig.simulators.instruments.lineserver import LineServer
from rig.simulators.physics import RoundingTicks, Ticks
from rig.simulators.records import Crossing
from rig.simulators.world import SimWorld

IDN = "bat-rig simulator,53230A-SIM,SIM-C001,sim-1"
ERROR_QUEUE = 20  # entries; past this the newest is replaced by -350 "Queue overflow", as SCPI says
_WORDS = {
    "INPut:SLOPe": ("POS", "NEG", "POSITIVE", "NEGATIVE"),
    "TRIGger:SOURce": ("IMM", "IMMEDIATE", "EXT", "EXTERNAL", "BUS"),
}
FAULTS = (
    "short_on_shot", "short_by", "miss_rebound_on_shot", "miss_rebound_gate", "silent_on_shot",
    "garble_on_shot", "drop_on_shot", "resolution_ps",
)  # fmt: skip


@dataclass
class _Stamp:
    time_s: float  # virtual time of the beam break
    value_s: float  # the stamp as read: since INIT, with the scene's timing noise, quantized
    shot: int


class ScpiCounterTwin:
    """The counter: `start()` serves it on a local port; `device_table()` is its rig config table.

    Fault options (shot = the world's FIRE count, 1-based; 0 = never): `short_on_shot` misses the
    last `short_by` edges of that shot; `miss_rebound_on_shot` misses the rebound edge of gate
    `miss_rebound_gate` (1-3, default 3) of that shot (gate 3: the near screen missed on the way
    back; gate 1: the far one, as a rebound under it); `silent_on_shot` never answers its FETC?;
    `garble_on_shot` spoils one byte of its first FETC? reply; `drop_on_shot` closes the connection on
    its FETC?.
    """

    DRIVER: ClassVar[str] = "scpi-counter"
    KIND: ClassVar[str] = "gates"

    def __init__(self, world: SimWorld, **fault_options: Any) -> None:
        unknown = sorted(set(fault_options) - set(FAULTS))
        if unknown:
            raise ValueError(
                f"scpi-counter twin has no option {unknown[0]!r} (it takes: {', '.join(FAULTS)})"
            )
        if not 1 <= int(fault_options.get("miss_rebound_gate", 3)) <= codec.N_GATES:
            raise ValueError(f"miss_rebound_gate must be 1-{codec.N_GATES}")
        self.world = world
        self.faults = {k: int(v) for k, v in fault_options.items() if k != "resolution_ps"}
        self.resolution_s = float(fault_options.get("resolution_ps", 20.0)) * 1e-12
        self._latch = _latch_for(world, self.resolution_s)
        self.errors: deque[tuple[int, str]] = deque()
        self.received: list[str] = []  # every command line, in order (tests read it)
        self._reset()
        self._garbled: set[int] = set()
        self._server = LineServer(self.handle, "scpi-counter", drops=self._drops)
        self.address = ""
        world.crossing_listeners.append(self._on_crossings)

    # -- instrument state ----------------------------------------------------------------------------
    def _reset(self) -> None:
        self.settings: dict[str, str] = {}
        self.mode: str | None = None
        self.count = 100
        self.channel = codec.CHANNEL
        self.timeout_s = 1.0
        self.running = False
        self.init_time = 0.0
        self.stamps: list[_Stamp] = []

    def _on_crossings(self, crossings: list[Crossing], ticks: tuple[tuple[int, int], ...], shot: int) -> None:
        """World hook: stamp the beam breaks of a shot fired while a measurement runs (on channel 1)."""
        if not self.running or self.channel != codec.CHANNEL:
            return
        missing = self.faults.get("short_by", 2) if shot == self.faults.get("short_on_shot", 0) else 0
        kept = sorted(crossings, key=lambda c: c.time_s)
        if shot == self.faults.get("miss_rebound_on_shot", 0):
            blind = self.faults.get("miss_rebound_gate", 3)
            kept = [c for c in kept if c.inbound or c.gate != blind]
        for c in kept[: max(0, len(kept) - missing)]:
            value = self._latch.latch(c.gate, c.time_s - self.init_time) * self.resolution_s
            self.stamps.append(_Stamp(c.time_s, value, shot))

    def _fetch(self) -> str | None:
        """FETC?: the stamps once the measurement is over, in virtual time; None = no reply."""
        world = self.world
        with world.lock:
            if self.mode != "TST" or (not self.running and not self.stamps):
                self._push(-230, "Data corrupt or stale")
                return None
            deadline = self.init_time + self.timeout_s
            inside = [s for s in self.stamps if s.time_s <= deadline]
            if len(inside) >= self.count:
                taken: list[_Stamp] = inside[: self.count]
                done = taken[-1].time_s
            else:
                taken, done = inside, deadline
            world.advance_to(done)
            self.running = False
            self.stamps = taken
            shot = taken[0].shot if taken else 0
            values: list[float | None] = [s.value_s for s in taken]
            values += [None] * (self.count - len(values))
        if shot and shot == self.faults.get("silent_on_shot", 0):
            return None
        reply = codec.format_stamps(values)
        if shot and shot == self.faults.get("garble_on_shot", 0) and shot not in self._garbled:
            self._garbled.add(shot)
            reply = reply[:5] + "#" + reply[6:]
        return reply

    def _push(self, code: int, text: str) -> None:
        if len(self.errors) >= ERROR_QUEUE:
            self.errors[-1] = (-350, "Queue overflow")
        else:
            self.errors.append((code, text))

    def handle(self, line: str) -> str | None:
        """One program message -> its reply line, or None (commands, unanswered queries)."""
        self.received.append(line)
        cmd = codec.parse_command(line)
        if cmd is None:
            self._push(-113, "Undefined header")
            return None
        try:
            return self._execute(cmd)
        except ValueError:
            self._push(-224, "Illegal parameter value")
            return None

    def _execute(self, cmd: codec.ScpiCommand) -> str | None:
        h, arg = cmd.header, cmd.argument
        if h == "*IDN?":
            return IDN
        if h == "*OPC?":
            return "1"
        if h == "*TST?":
            return "+0"
        if h == "*RST":
            with self.world.lock:
                self._reset()
        elif h == "*CLS":
            self.errors.clear()
        elif h == "SYSTem:ERRor?":
            code, text = self.errors.popleft() if self.errors else (0, "No error")
            return f'{code:+d},"{text}"'
        elif h == "SYSTem:TIMeout":
            self.timeout_s = _number(arg, 0.001, 1e5)
        elif h == "CONFigure:ARRay:TSTamp":
            self.count = codec.parse_array_count(arg)
            channel = arg.partition(",")[2].strip()
            self.channel = int(channel.strip("()@ ") or codec.CHANNEL) if channel else codec.CHANNEL
            self.mode = "TST"
        elif h == "SAMPle:COUNt":
            self.count = int(_number(arg, 1, 1_000_000))
        elif h == "INPut:COUPling" and arg.upper() in ("AC", "DC"):
            self.settings[h] = arg.upper()
        elif arg.upper() in _WORDS.get(h, ()):
            self.settings[h] = arg.upper()[:3]
        elif h in ("INPut:IMPedance", "INPut:LEVel", "SENSe:TSTamp:RATE", "TSTamp:RATE"):
            self.settings[h] = repr(_number(arg, -1e7, 1e7))
        elif h == "INITiate":
            with self.world.lock:
                if self.mode != "TST":
                    self._push(-221, "Settings conflict")
                    return None
                self.running, self.init_time, self.stamps = True, self.world.clock, []
        elif h == "FETCh?":
            return self._fetch()
        elif h == "ABORt":
            with self.world.lock:
                self.running = False
        else:
            raise ValueError(h)  # a known header with a value it does not take
        return None

    # -- the wire ------------------------------------------------------------------------------------
    def start(self, host: str = "127.0.0.1", port: int = 0) -> str:
        """Listen on `host:port` (0: any free port) in a daemon thread; the VISA resource to open."""
        self.address = f"TCPIP0::{host}::{self._server.start(host, port)}::SOCKET"
        return self.address

    def device_table(self) -> dict[str, Any]:
        """The `[devices.gates]` table of a rig config that uses this twin."""
        if not self.address:
            raise RuntimeError("the twin is not serving yet: it has no address")
        options = {"resolution_ps": round(self.resolution_s * 1e12, 6)}
        return {"driver": self.DRIVER, "address": self.address, "options": options, "simulated": True}

    def close(self) -> None:
        """Stop listening and hang up; the world forgets this front end."""
        with contextlib.suppress(ValueError):
            self.world.crossing_listeners.remove(self._on_crossings)
        self._server.close()

    def _hang_up(self) -> None:
        self._server.hang_up()

    def _drops(self, line: str) -> bool:
        """The drop fault: the connection goes when the shot's FETC? comes."""
        shot = self.faults.get("drop_on_shot", 0)
        cmd = codec.parse_command(line)
        if not shot or cmd is None or cmd.header != "FETCh?":
            return False
        with self.world.lock:
            hit = any(s.shot == shot for s in self.stamps)
        if hit:
            self.faults["drop_on_shot"] = 0  # once: the replugged counter works again
        return hit


def _number(text: str, low: float, high: float) -> float:
    value = float(text.strip())
    if not low <= value <= high:
        raise ValueError(text)
    return value


def _latch_for(world: SimWorld, resolution_s: float) -> Ticks:
    """The counter's latch: the scene's gate timing (latency, jitter, a phase of its own) at the
    counter's resolution, on its own random stream; without that effect, rounding to the resolution."""
    timing = next((e for e in world.effects if isinstance(e, GateTiming)), None)
    if timing is None:
        return RoundingTicks(resolution_s)
    latch = GateTiming(timing.config, world.scene, random.Random(f"{world.scene.run_key()}/scpi-counter"))
    latch.tick_s = resolution_s
    return latch

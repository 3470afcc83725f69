"""A minimal host for byte-level tests: HostCodec commands in, replies and events out."""

from __future__ import annotations

import serial

from rig.drivers.cannon.codec import SPECS as CANNON_SPECS
from rig.drivers.clamp.codec import SPECS as CLAMP_SPECS
from rig.drivers.codec import HostCodec
from rig.drivers.gates.codec import SPECS as GATES_SPECS
from rig.drivers.wire import ErrorReply, Event, Garbled, Item, Reply
from rig.simulators.device import SimDevice
from rig.simulators.world import SimWorld

SPECS = {"cannon": CANNON_SPECS, "gates": GATES_SPECS, "clamp": CLAMP_SPECS}


class Host:
    """Talks to one simulated device through its codec; keeps every event and garbled line."""

    def __init__(self, device: SimDevice) -> None:
        self.device = device
        self.codec = HostCodec(SPECS[device.name])
        self.events: list[Event] = []
        self.garbled: list[Garbled] = []

    def send(self, verb: str, *args: object, drain: bool = False) -> Reply | ErrorReply | None:
        """Send one command; return its reply (None if none came). `drain` also reads every event."""
        seq, data = self.codec.command(verb, *args)
        self.device.write(data)
        reply = None
        while reply is None:
            chunk = self.device.read(1)
            if not chunk:
                break
            for item in self.codec.feed(chunk):
                if isinstance(item, Reply | ErrorReply) and item.seq == seq:
                    reply = item
                else:
                    self._keep(item)
        if drain:
            self.drain()
        return reply

    def drain(self) -> list[Event]:
        """Read everything queued (moving the clock to the last of it); return the new events."""
        before = len(self.events)
        for item in self.codec.feed(self.device.read()):
            self._keep(item)
        return self.events[before:]

    def _keep(self, item: Item) -> None:
        if isinstance(item, Event):
            self.events.append(item)
        elif isinstance(item, Garbled):
            self.garbled.append(item)

    def ok(self, verb: str, *args: object) -> Reply:
        """Send and insist on an OK reply."""
        reply = self.send(verb, *args)
        assert isinstance(reply, Reply), f"{verb} -> {reply}"
        return reply


class Port:
    """A HostCodec over a pyserial port (sim://, socket:// or a pty path)."""

    def __init__(self, url: str, device: str, timeout: float = 0.5) -> None:
        self.port = serial.serial_for_url(url, timeout=timeout)
        self.codec = HostCodec(SPECS[device])
        self.events: list[Event] = []

    def ask(self, verb: str, *args: object) -> Reply:
        """Send a command and return its OK reply, keeping events that arrive meanwhile."""
        seq, frame = self.codec.command(verb, *args)
        self.port.write(frame)
        while True:
            line = self.port.read_until(b"\n")
            assert line, f"no reply to {verb}"
            for item in self.codec.feed(line):
                if isinstance(item, Reply) and item.seq == seq:
                    return item
                if isinstance(item, Event):
                    self.events.append(item)

    def wait_event(self, name: str) -> Event:
        """The next event called `name` (earlier ones of other names are kept)."""
        while True:
            found = [e for e in self.events if e.name == name]
            if found:
                self.events.remove(found[0])
                return found[0]
            line = self.port.read_until(b"\n")
            assert line, f"no {name} event"
            self.events += [i for i in self.codec.feed(line) if isinstance(i, Event)]


class Rig:
    """The three hosts of one world, with the steps of an ordinary shot."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world
        self.cannon = Host(world.cannon)
        self.gates = Host(world.gates)
        self.clamp = Host(world.clamp)

    def prepare(self, pressure_kpa: float, position_mm: float | None = None) -> None:
        """Lock the grip, place the stage, arm the gates, fill the tank and wait for READY."""
        self.clamp.ok("CLAMP")
        if position_mm is not None:
            self.clamp.ok("MOVE", position_mm)
        self.clamp.drain()
        self.gates.ok("ARM")
        self.cannon.ok("PSET", pressure_kpa)
        self.cannon.drain()

    def shot(self, pressure_kpa: float, position_mm: float | None = None) -> list[Event]:
        """Prepare, ARM, FIRE and collect the gate events of one shot."""
        self.prepare(pressure_kpa, position_mm)
        self.cannon.ok("ARM")
        self.cannon.ok("FIRE")
        return [e for e in self.gates.drain() if e.name == "G"]

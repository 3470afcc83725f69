"""VxmStageTwin: a VXM stage and a swing sensor on TCP, a second wire front end on the SimWorld's clamp.

The state is the world's (rig.simulators.clamp.SimClamp): the carriage position that `fire()` takes
as the impact point, the grip and its interlock, the swing, and each impact's recoil (heard through
`SimClamp.recoil_listeners`). Virtual time: a program's `^` is sent once the world's clock has been
advanced to the carriage's arrival; GRIP answers when the lock switch agrees, CAP when its last
sample is taken, TRIG? when a capture under way is complete - each bounded by the instrument's own
limit, never by wall time. The stage's screw has play: the carriage stays within
[mm(motor), mm(motor) + backlash_mm], so a target approached from above is off by the play.
"""

from __future__ import annotations

import contextlib
import math
import socket
import threading
from collections.abc import Callable
from typing import Any, ClassVar

from rig.drivers.vxm import stage_codec, swing_codec
from rig.drivers.vxm.stage_codec import Index, Speed
from rig.simulators.clamp import LIFT_S
from rig.simulators.ptybridge import PtyBridge
from rig.simulators.world import RECOIL_REPORT_S, SimWorld

GRIP_WAIT_S = 2.0  # the box waits this long for the lock switch [assumed]
TRIG_WAIT_S = 1.0  # TRIG? waits this long for a capture under way [assumed]
PROGRAM_LIMIT_S = 600.0  # a program longer than this is refused (no stage crosses a bat that slowly)
RESOLUTION_DEG = 360.0 / 2**14  # a 14-bit absolute encoder [assumed]
IDENTITY = "VXM-SIM sim-1"
SENSOR_ID = "ID,bat-rig simulator,SWS-SIM,SIM-S001,sim-1"


class _Drop(Exception):
    """Close the connection (a fault)."""


class _Server:
    """One TCP port on a daemon thread: bytes in -> `handle` -> bytes out; one client at a time."""

    def __init__(self, name: str, handle: Callable[[bytes], bytes], host: str, port: int) -> None:
        self.handle = handle
        self.sock = socket.create_server((host, port))
        self.sock.settimeout(0.2)
        self._stop = threading.Event()
        self._conn: socket.socket | None = None
        self._thread = threading.Thread(target=self._run, name=f"twin-{name}", daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        host, port = self.sock.getsockname()[:2]
        return f"socket://{host}:{port}"

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self._conn = conn
            conn.settimeout(0.2)
            with conn:
                self._serve(conn)

    def _serve(self, conn: socket.socket) -> None:
        while not self._stop.is_set():
            try:
                data = conn.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return
            try:
                out = self.handle(data)
            except _Drop:
                return
            if out:
                try:
                    conn.sendall(out)
                except OSError:
                    return

    def close(self) -> None:
        self._stop.set()
        with contextlib.suppress(OSError):
            self.sock.close()
        if self._conn is not None:
            with contextlib.suppress(OSError):
                self._conn.close()
        self._thread.join(2.0)


class VxmStageTwin:
    """The `vxm-stage` clamp's two instruments on one SimWorld (faults are counted per run/command).

    Faults: `stage_silent_after=n` (the stage runs n programs, then answers nothing: no `^`, no
    V or X), `drop_after=n` (it closes the connection at program n+1), `sensor_silent_after=n`
    (the sensor answers n commands, then nothing).
    """

    DRIVER: ClassVar[str] = "vxm-stage"
    KIND: ClassVar[str] = "clamp"
    SERIAL: ClassVar[bool] = True  # serial=True serves it on a pty
    PORTS: ClassVar[int] = 2  # the stage's and the sensor's

    def __init__(
        self,
        world: SimWorld,
        *,
        backlash_mm: float = 0.05,
        lead_mm_per_step: float = stage_codec.LEAD_MM_PER_STEP,
        zero_mm: float = 0.0,
        resolution_deg: float = RESOLUTION_DEG,
        stage_silent_after: int | None = None,
        drop_after: int | None = None,
        sensor_silent_after: int | None = None,
        serial: bool = False,
    ) -> None:
        self.serial = serial  # serve each instrument on a pty (its serial port) in front of its TCP port
        self._bridges: list[PtyBridge] = []
        self.world, self.clamp = world, world.clamp
        self.backlash_mm, self.resolution_deg = backlash_mm, resolution_deg
        self.lead, self.zero_mm = lead_mm_per_step, zero_mm
        self.stage_silent_after, self.drop_after = stage_silent_after, drop_after
        self.sensor_silent_after = sensor_silent_after
        self.motor = round((self.clamp.position_mm() - zero_mm) / lead_mm_per_step)
        self.carriage_mm = self._mm(self.motor)
        with world.lock:
            self.clamp.start_move(self.carriage_mm, 0.0)
        self.speed_sps = 2000
        self._arrival = world.clock
        self.program: list[Index | Speed] = []
        self.runs = self.sensor_commands = 0
        self.silent = False
        self._tokens = stage_codec.DeviceTokenizer()
        self._sensor_buf = b""
        self._arm: tuple[float, int, int, float] | None = None  # hz, pre, post, deg/s
        self._trig: tuple[int, float, float, tuple[float, int, int, float]] | None = None
        self._servers: list[_Server] = []
        self.clamp.recoil_listeners.append(self._recoil)

    # -- the API `rig sim serve --instruments` uses -----------------------------------------
    def start(self, host: str = "127.0.0.1", port: int = 0) -> str:
        """Serve the stage on `port` and the sensor on `port + 1` (both free ports if 0); the stage's URL."""
        self._servers = [
            _Server("vxm-stage", self._stage, host, port),
            _Server("swing-sensor", self._sensor, host, port + 1 if port else 0),
        ]
        if self.serial:
            for server in self._servers:
                bound_host, bound_port = server.sock.getsockname()[:2]
                self._bridges.append(PtyBridge(bound_host, bound_port))
                self._bridges[-1].start()
        return self.urls()[0]

    def urls(self) -> list[str]:
        """Where the stage and the sensor are: pty paths when serving serial, else socket:// URLs."""
        return [b.path for b in self._bridges] if self.serial else [s.url for s in self._servers]

    def device_table(self) -> dict[str, Any]:
        """The rig config's [devices.clamp] table for this twin (the sensor's URL among the options)."""
        if not self._servers:
            raise RuntimeError("the twin is not serving yet: it has no address")
        stage, sensor = self.urls()
        options = {
            "sensor": sensor,
            "lead_mm_per_step": self.lead,
            "zero_mm": self.zero_mm,
            "backlash_mm": max(0.1, 2 * self.backlash_mm),
        }
        return {"driver": self.DRIVER, "address": stage, "options": options, "simulated": True}

    def touch(self, omega_rad_s: float = 3.0) -> None:
        """Someone moves the bat by hand now (an operator between the stage's move and FIRE): the
        armed sensor captures it as it would an impact's recoil, if `omega_rad_s` passes its
        threshold. Not a shot: the world records nothing."""
        with self.world.lock:
            self._recoil(omega_rad_s, self.world.clock + RECOIL_REPORT_S, 0)

    def close(self) -> None:
        """Stop serving; the world's clamp forgets this twin."""
        for bridge in self._bridges:
            bridge.close()
        for server in self._servers:
            server.close()
        with contextlib.suppress(ValueError):
            self.clamp.recoil_listeners.remove(self._recoil)

    # -- the stage ---------------------------------------------------------------------------
    def _mm(self, steps: int) -> float:
        return self.zero_mm + steps * self.lead

    def _stage(self, data: bytes) -> bytes:
        out = b""
        with self.world.lock:
            for token in self._tokens.feed(data):
                if self.silent:
                    continue
                if token == "R":
                    self.runs += 1
                    if self.drop_after is not None and self.runs > self.drop_after:
                        raise _Drop
                    if self.stage_silent_after is not None and self.runs > self.stage_silent_after:
                        self.silent = True
                        continue
                    out += self._run()
                elif token == "C":
                    self.program = []
                elif token == "V":
                    out += b"B" if self.world.clock < self._arrival else b"R"
                elif token == "X":
                    out += stage_codec.encode_position(self.motor)
                elif token == stage_codec.IDENTITY_QUERY:
                    out += f"{IDENTITY}\r".encode("ascii")
                elif token in stage_codec.IMMEDIATE:
                    continue  # F, E, Q, K, N: nothing to answer
                else:
                    with contextlib.suppress(ValueError):  # [assumed] a VXM ignores what it cannot parse
                        self.program.append(stage_codec.parse_program_token(token))
        return out

    def _run(self) -> bytes:
        duration = 0.0
        for item in self.program:
            if isinstance(item, Speed):
                self.speed_sps = item.sps
                continue
            if item.zero:
                self.zero_mm, self.motor = self._mm(self.motor), 0
                continue
            target = item.steps if item.absolute else self.motor + item.steps
            duration += abs(target - self.motor) / self.speed_sps
            self.motor = target
            low = self._mm(target)
            self.carriage_mm = min(max(self.carriage_mm, low), low + self.backlash_mm)
        if duration > PROGRAM_LIMIT_S:
            return b""
        self._arrival = self.clamp.start_move(self.carriage_mm, duration)
        self.world.advance_to(self._arrival)
        return b"^"

    # -- the swing sensor --------------------------------------------------------------------
    def _sensor(self, data: bytes) -> bytes:
        self._sensor_buf += data
        out: list[str] = []
        with self.world.lock:
            while b"\r" in self._sensor_buf:
                raw, _, self._sensor_buf = self._sensor_buf.partition(b"\r")
                self.sensor_commands += 1
                if self.sensor_silent_after is not None and self.sensor_commands > self.sensor_silent_after:
                    continue
                try:
                    out += self._command(swing_codec.parse_command(raw.decode("ascii", errors="replace")))
                except ValueError as exc:
                    out.append(f"ERR {exc}")
        return swing_codec.encode_lines(out)

    def _command(self, cmd: swing_codec.Command) -> list[str]:
        verb, args, world, clamp = cmd.verb, cmd.args, self.world, self.clamp
        if verb == "ID?":
            return [SENSOR_ID]
        if verb == "RES?":
            return [f"RES,{self.resolution_deg:.8g}"]
        if verb == "LOCK?":
            return [f"LOCK,{int(clamp.locked)}"]
        if verb == "GRIP":
            when = clamp.grip(bool(args[0]))
            if when - world.clock > GRIP_WAIT_S:
                return [f"ERR GRIP lock switch did not agree within {GRIP_WAIT_S:g} s"]
            world.advance_to(when)
            return [f"LOCK,{int(clamp.locked)}"]
        if verb == "SWING":
            if not clamp.locked:
                return ["ERR SWING grip not locked"]
            if not 1 <= args[0] <= 100:
                raise ValueError("SWING takes 1-100 cycles")
            clamp.start_swing(int(args[0]))
            self._swing_trigger()
            return ["OK"]
        if verb == "CAP":
            return self._capture(int(args[0]), args[1])
        if verb == "ARM":
            hz, pre, post, deg_s = args
            if not (1.0 <= hz <= 20000.0 and pre >= 0 and post >= 1) or pre + post > swing_codec.MAX_SAMPLES:
                raise ValueError("ARM takes a rate of 1-20000 Hz and pre + post within the buffer")
            self._arm = (hz, int(pre), int(post), deg_s)
            return ["OK"]
        return self._triggered()

    def _quantized(self, deg: float) -> float:
        return round(deg / self.resolution_deg) * self.resolution_deg

    def _capture(self, n: int, hz: float) -> list[str]:
        if not (1 <= n <= swing_codec.MAX_SAMPLES and 1.0 <= hz <= 20000.0):
            raise ValueError(f"CAP takes 1-{swing_codec.MAX_SAMPLES} samples at 1-20000 Hz")
        k0 = math.ceil(self.world.clock * hz - 1e-9)
        times = [(k0 + i) / hz for i in range(n)]
        self.world.advance_to(times[-1])
        lines = [swing_codec.encode_sample(t, self._quantized(self.clamp.angle_at(t))) for t in times]
        return [f"#CAP,{n}", *lines, "#END"]

    def _swing_trigger(self) -> None:
        """The armed sensor triggers on the pendulum's own swing too, when its peak speed (a quarter
        period after release) passes the threshold: as a real one would, whatever the host meant."""
        period = self.world.swing_period()
        omega = math.radians(self.world.scene.rig.swing_amplitude_deg) * 2.0 * math.pi / period
        release = self.world.clock + LIFT_S
        self._recoil(omega, release + period / 4.0 + RECOIL_REPORT_S, 0)

    def _recoil(self, omega: float, at: float, shot: int) -> None:
        if self._arm is None or math.degrees(abs(omega)) < self._arm[3]:
            return
        count = self._trig[0] + 1 if self._trig else 1
        self._trig = (count, at - RECOIL_REPORT_S, omega, self._arm)

    def _triggered(self) -> list[str]:
        if self._trig is None:
            return ["#TRIG,0,0", "#END"]
        count, t_step, omega, (hz, pre, post, _) = self._trig
        first = math.ceil(t_step * hz - 1e-9)  # the first sample the speed is above threshold
        times = [(first + i) / hz for i in range(-pre, post)]
        if self.world.clock < times[-1] <= self.world.clock + TRIG_WAIT_S:
            self.world.advance_to(times[-1])
        elif times[-1] > self.world.clock:
            return [f"#TRIG,{count - 1},0", "#END"]  # still capturing: the last complete one is older
        rate = math.degrees(omega)
        lines = [swing_codec.encode_sample(t, self._quantized(rate * max(0.0, t - t_step))) for t in times]
        return [f"#TRIG,{count},{len(lines)}", *lines, "#END"]

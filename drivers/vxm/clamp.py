"""The `vxm-stage` clamp: a VXM stepper stage for the impact point plus a swing sensor with the grip.

Two connections (both pyserial URLs through rig.drivers.transport.open_port): the stage at the
device's `address`, the swing sensor at the `sensor` option. Both are read synchronously with a
deadline on every wait; every byte in is recorded through `on_traffic` before it is parsed, every
byte out once its write succeeded (a reply is read only after the write returned, so the record
keeps the wire's order, and a failed write leaves no bytes that never left).
The period and the recoil are computed on the host (rig.measure.swing); the last estimates, with
their standard uncertainties, stay on `last_period` and `last_recoil`.
"""

from __future__ import annotations

import collections
import logging
import math
import time
from collections.abc import Callable
from typing import Any, Self

from rig.core.devices import STAGE_RANGE_MM, ClampStatus, InstrumentIdentity, PendulumPeriod, Recoil
from rig.core.errors import (
    DeviceError,
    DeviceGone,
    DeviceRefused,
    DeviceTimeout,
    GarbledReply,
    NotSent,
    ParameterError,
)
from rig.drivers.connection import SerialLike
from rig.drivers.registry import DriverContext
from rig.drivers.traffic import TrafficLog, TrafficRecord
from rig.drivers.transport import open_port
from rig.drivers.vxm import stage_codec, swing_codec
from rig.drivers.vxm.stage_codec import Done, Junk, Line, StageGeometry, StageItem, Status
from rig.measure.swing import PeriodEstimate, RecoilEstimate, recoil_speed, swing_period

log = logging.getLogger(__name__)

NUMBER = (int, float)
ZERO_ALLOWED = frozenset({"backlash_mm", "pre_samples", "motor"})  # may be 0 (zero_mm: any finite value)
OPTIONS: dict[str, type | tuple[type, ...]] = {
    "sensor": str,
    "lead_mm_per_step": NUMBER,
    "zero_mm": NUMBER,
    "backlash_mm": NUMBER,
    "motor": int,
    "speed_steps_s": int,
    "sample_hz": NUMBER,
    "period_hz": NUMBER,
    "max_period_s": NUMBER,
    "settle_s": NUMBER,
    "position_tolerance_mm": NUMBER,
    "trigger_deg_s": NUMBER,
    "pre_samples": int,
    "post_samples": int,
    "recoil_window": int,
    "serial_number": str,
}


DRAIN_BYTES = 1 << 16  # one read's most


class _Link:
    """One port: writes and reads recorded, every failure a one-line DeviceGone."""

    def __init__(self, device: str, what: str, port: SerialLike, traffic: TrafficLog) -> None:
        self.device, self.what, self.port, self.traffic = device, what, port, traffic

    def send(self, data: bytes) -> None:
        """Write `data`; recorded (stamped when handed over) only once the write succeeded."""
        started = time.monotonic()
        try:
            self.port.write(data)
        except OSError as exc:
            raise DeviceGone(self.device, f"{self.what}: write failed: {exc}") from exc
        self.traffic.add("tx", data, started)

    def read(self) -> bytes:
        """What has arrived (waiting up to the port's timeout for the first byte)."""
        try:
            data = self.port.read(max(1, self.port.in_waiting))
            if len(data) == 1:  # a socket:// port says 1 for "readable": take the rest without waiting
                data += self._drain()
        except OSError as exc:
            raise DeviceGone(self.device, f"{self.what} connection lost: {exc}") from exc
        if data:
            self.traffic.add("rx", data)
        return bytes(data)

    def _drain(self) -> bytes:
        """Everything already received, without blocking (a sensor's block of samples comes at once)."""
        saved = self.port.timeout
        self.port.timeout = 0
        try:
            return bytes(self.port.read(DRAIN_BYTES))
        finally:
            self.port.timeout = saved

    def close(self) -> None:
        try:
            self.port.close()
        except Exception:  # a port already gone closes quietly
            log.debug("%s: close failed", self.what, exc_info=True)


class VxmClamp:
    """rig.core.devices.Clamp on a VXM stage (impact point) and a swing sensor (grip, angle)."""

    def __init__(
        self,
        stage: SerialLike,
        sensor: SerialLike,
        *,
        name: str = "clamp",
        geometry: StageGeometry | None = None,
        motor: int = 1,
        speed_steps_s: int = 2000,
        reply_timeout_s: float = 1.0,
        stage_timeout_s: float = 30.0,
        sample_hz: float = 2000.0,
        period_hz: float = 200.0,
        max_period_s: float = 2.0,
        settle_s: float = 1.5,
        position_tolerance_mm: float = 0.05,
        trigger_deg_s: float = 30.0,
        pre_samples: int = 20,
        post_samples: int = 40,
        recoil_window: int = 8,
        serial_number: str = "",
        on_traffic: Callable[[TrafficRecord], None] | None = None,
    ) -> None:
        self.name = name
        self.traffic = TrafficLog(on_traffic)
        self.geometry = geometry or StageGeometry()
        self.motor, self.speed_steps_s = motor, speed_steps_s
        self.reply_timeout_s, self.stage_timeout_s = reply_timeout_s, stage_timeout_s
        self.sample_hz, self.period_hz = sample_hz, period_hz
        self.max_period_s, self.settle_s = max_period_s, settle_s
        self.position_tolerance_mm = position_tolerance_mm
        self.recoil_window, self.serial_number = recoil_window, serial_number
        self.last_period: PeriodEstimate | None = None
        self.last_recoil: RecoilEstimate | None = None
        self._stage = _Link(name, "stage", stage, self.traffic)
        self._sensor = _Link(name, "swing sensor", sensor, self.traffic)
        self._decoder = stage_codec.HostDecoder()
        self._items: collections.deque[StageItem] = collections.deque()
        self._splitter = swing_codec.LineSplitter()
        self._lines: collections.deque[str | bytes] = collections.deque()
        self._stage.send(b"F")  # on line, no echo
        self._stage_query(b"V", Status, "V (status)")
        self.resolution_deg = float(self._sensor_reply("RES?", prefix="RES,").split(",")[1])
        self._sensor_reply("ARM", sample_hz, pre_samples, post_samples, trigger_deg_s, prefix="OK")
        self._last_trigger = self._sensor_block("TRIG?", self.reply_timeout_s)[0]

    @classmethod
    def from_context(cls, context: DriverContext) -> Self:
        """The driver a rig config's [devices.clamp] table names `vxm-stage`."""
        opts: dict[str, Any] = context.only_options(OPTIONS)
        if "sensor" not in opts:
            raise context.refuse("option 'sensor' (the swing sensor's address) is required")
        for key, value in opts.items():  # every number a rate, a length, a count: finite, and > 0 but these
            if (
                key != "zero_mm"
                and isinstance(value, int | float)
                and not (math.isfinite(value) and (value >= 0 if key in ZERO_ALLOWED else value > 0))
            ):
                raise context.refuse(
                    f"option {key!r} must be {'>= 0' if key in ZERO_ALLOWED else '> 0'}, not {value!r}"
                )
        geometry = StageGeometry(
            float(opts.pop("lead_mm_per_step", stage_codec.LEAD_MM_PER_STEP)),
            float(opts.pop("zero_mm", 0.0)),
            float(opts.pop("backlash_mm", 0.1)),
        )
        sensor_url = opts.pop("sensor")
        stage = open_port(context.address, device=f"{context.kind} stage", baudrate=stage_codec.BAUDRATE)
        try:
            sensor = open_port(
                sensor_url, device=f"{context.kind} swing sensor", baudrate=swing_codec.BAUDRATE
            )
        except BaseException:
            stage.close()
            raise
        try:
            return cls(
                stage,
                sensor,
                name=context.kind,
                geometry=geometry,
                reply_timeout_s=context.timeouts.reply_s,
                stage_timeout_s=context.timeouts.stage_s,
                on_traffic=context.on_traffic,
                **opts,
            )
        except BaseException:
            stage.close()
            sensor.close()
            raise

    # -- the Clamp interface -----------------------------------------------------------------
    def status(self) -> ClampStatus:
        """Grip, stage position and motion, pivot angle (one sample)."""
        moving = self._stage_query(b"V", Status, "V (status)").char in "Bb"
        position = self.geometry.mm_for(self._position_steps())
        locked = self._sensor_reply("LOCK?", prefix="LOCK,") == "LOCK,1"
        _, _, angles = self._sensor_block_of("CAP", 1, self.period_hz)
        return ClampStatus(locked, position, moving, angles[0])

    def clamp(self) -> None:
        """Close the grip; returns once the lock switch says locked."""
        self._grip(True)

    def release(self) -> None:
        """Open the grip; returns once the lock switch says open."""
        self._grip(False)

    def move_to(self, mm: float) -> None:
        """Stage to `mm` from the pivot, approached from below; checked by X within the tolerance.
        Captures the sensor made before (a swing-back of the last shot) are set aside here, and
        again in `before_fire`."""
        low, high = STAGE_RANGE_MM
        if not low <= float(mm) <= high:
            raise NotSent(self.name, "move", f"{float(mm):g} mm is outside the stage's {low:g}-{high:g} mm")
        target = self.geometry.steps_for(float(mm))
        legs = self.geometry.legs(self._position_steps(), target)
        self._items.clear()
        self._stage.send(stage_codec.program(legs, self.motor, self.speed_steps_s))
        self._wait_stage(
            Done,
            self.stage_timeout_s,
            f"the stage did not acknowledge the move to {float(mm):g} mm (no '^')",
        )
        reached = self.geometry.mm_for(self._position_steps())
        if abs(reached - float(mm)) > self.position_tolerance_mm:
            raise DeviceError(self.name, f"stage stopped at {reached:.3f} mm, asked for {float(mm):g} mm")
        self._forget_captures()

    def measure_period(self, cycles: int) -> PendulumPeriod:
        """Lift and drop the bat, sample its swing, and time `cycles` periods on the host."""
        self._sensor_reply("SWING", cycles + 1, prefix="OK")
        seconds = self.settle_s + (cycles + 1) * self.max_period_s
        n = min(swing_codec.MAX_SAMPLES, math.ceil(seconds * self.period_hz))
        _, times, angles = self._sensor_block_of("CAP", n, self.period_hz)
        try:
            est = swing_period(times, angles, cycles, self.resolution_deg, 1e-6)
        except ParameterError as exc:
            raise DeviceError(self.name, f"swing sensor trace gives no period: {exc}") from None
        self.last_period = est
        self._forget_captures()  # the swing itself may have triggered the recoil capture
        return PendulumPeriod(est.period_s, est.amplitude_deg, cycles, u_s=est.u_s)

    def before_fire(self) -> None:
        """rig.core.devices.FireAware: the cannon is about to fire. Captures made since the stage
        moved (an operator touching the bat before FIRE) are set aside, so that a shot which does
        not trigger the sensor reports no recoil rather than the touch."""
        self._forget_captures()

    def _forget_captures(self) -> None:
        """Take the sensor's trigger count as seen: a capture made before now (the pendulum's
        swing, the last shot's swing-back) is never taken for the next impact's recoil."""
        count, _, _ = self._sensor_block("TRIG?", self.reply_timeout_s)
        self._last_trigger = max(self._last_trigger, count)

    def next_recoil(self, timeout_s: float) -> Recoil | None:
        """The peak recoil speed of the next triggered capture, or None if none completes in time."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                count, times, angles = self._sensor_block("TRIG?", self.reply_timeout_s)
            except DeviceTimeout as exc:
                raise DeviceGone(self.name, f"swing sensor went silent: {exc}") from None
            if count > self._last_trigger and times:
                self._last_trigger = count
                try:
                    self.last_recoil = recoil_speed(
                        times, angles, self.resolution_deg, 1e-6, window=self.recoil_window
                    )
                except ParameterError as exc:
                    log.warning("%s: recoil capture %d not usable: %s", self.name, count, exc)
                    return None
                return Recoil(abs(self.last_recoil.omega_rad_s))
            if time.monotonic() >= deadline:
                return None
            time.sleep(0.002)

    def identify(self) -> InstrumentIdentity:
        """The stage's model and firmware ([assumed] `getDM`) and the sensor's ID line."""
        line = self._stage_query(stage_codec.IDENTITY_QUERY.encode() + b",", Line, "getDM (identity)")
        model, _, firmware = line.text.partition(" ")
        parts = self._sensor_reply("ID?", prefix="ID,").split(",")
        if len(parts) != 5:
            raise GarbledReply(self.name, f"swing sensor ID reply has {len(parts)} fields, 5 expected")
        _, maker, s_model, s_serial, s_fw = parts
        return InstrumentIdentity(
            model=f"{model} + {s_model}",
            firmware=f"{firmware or '?'} / {s_fw}",
            serial_number=f"{self.serial_number or '?'} / {s_serial}",
            maker=f"Velmex (VXM class) / {maker}",
        )

    def close(self) -> None:
        """Close both connections."""
        self._stage.close()
        self._sensor.close()

    # -- the stage ---------------------------------------------------------------------------
    def _position_steps(self) -> int:
        line = self._stage_query(b"X", Line, "X (position)")
        try:
            return stage_codec.parse_position(line.text)
        except ValueError as exc:
            raise GarbledReply(self.name, f"stage: {exc}") from None

    def _stage_query(self, command: bytes, kind: type[Any], what: str) -> Any:
        self._items.clear()
        self._stage.send(command)
        return self._wait_stage(kind, self.reply_timeout_s, f"the stage did not answer {what}")

    def _wait_stage(self, kind: type[Any], timeout_s: float, silence: str) -> Any:
        deadline = time.monotonic() + timeout_s
        while True:
            while self._items:
                item = self._items.popleft()
                if isinstance(item, Junk):
                    raise GarbledReply(self.name, f"stage sent a garbled byte {item.data!r}")
                if isinstance(item, kind):
                    return item
            if time.monotonic() >= deadline:
                raise DeviceTimeout(self.name, f"{silence} within {timeout_s:g} s")
            self._items.extend(self._decoder.feed(self._stage.read()))

    # -- the swing sensor --------------------------------------------------------------------
    def _grip(self, locked: bool) -> None:
        want = f"LOCK,{int(locked)}"
        got = self._sensor_reply("GRIP", int(locked), prefix="LOCK,", timeout_s=self.reply_timeout_s + 5.0)
        if got != want:
            raise DeviceError(self.name, f"grip lock switch says {got!r} after GRIP {int(locked)}")

    def _line(self, deadline: float, what: str) -> str:
        while not self._lines:
            if time.monotonic() >= deadline:
                raise DeviceTimeout(self.name, f"swing sensor did not answer {what} in time")
            self._lines.extend(self._splitter.feed(self._sensor.read()))
        line = self._lines.popleft()
        if isinstance(line, bytes):
            raise GarbledReply(self.name, f"swing sensor sent a garbled line {line[:40]!r} to {what}")
        return line

    def _sensor_reply(self, verb: str, *args: float, prefix: str, timeout_s: float | None = None) -> str:
        self._lines.clear()
        self._sensor.send(swing_codec.encode(verb, *args))
        line = self._line(time.monotonic() + (timeout_s or self.reply_timeout_s), verb)
        if line.startswith("ERR"):
            raise DeviceRefused(self.name, verb, "ERR", line[3:].strip())
        if not line.startswith(prefix):
            raise GarbledReply(self.name, f"swing sensor answered {verb} with {line[:40]!r}")
        return line

    def _sensor_block_of(self, verb: str, n: int, hz: float) -> tuple[int, list[float], list[float]]:
        return self._sensor_block(f"{verb} {n} {hz:g}", self.reply_timeout_s + n / hz)

    def _sensor_block(self, command: str, timeout_s: float) -> tuple[int, list[float], list[float]]:
        """Send `command`; its `#CAP,n` / `#TRIG,k,n` block as (k or n, times, angles)."""
        self._lines.clear()
        self._sensor.send((command + "\r").encode("ascii"))
        verb = command.split()[0]
        deadline = time.monotonic() + timeout_s
        head = self._line(deadline, verb)
        if head.startswith("ERR"):
            raise DeviceRefused(self.name, verb, "ERR", head[3:].strip())
        fields = head.split(",")
        try:
            if fields[0] not in ("#CAP", "#TRIG"):
                raise ValueError(head[:40])
            count, n = int(fields[1]), int(fields[-1])
            times, angles = [], []
            for _ in range(n):
                t, a = swing_codec.parse_sample(self._line(deadline, verb))
                times.append(t)
                angles.append(a)
            if self._line(deadline, verb) != "#END":
                raise ValueError("block not ended by #END")
        except (ValueError, IndexError) as exc:
            raise GarbledReply(self.name, f"swing sensor's {verb} block is malformed: {exc}") from None
        return count, times, angles

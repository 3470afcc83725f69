"""The serial transport: the only module that imports pyserial.

`open_port` turns a URL into an open port (a device path, ``socket://``, ``spy://``, ``loop://`` or
any scheme registered in ``serial.protocol_handler_packages``, such as ``sim://``).
`LineTransport` owns one port and a reader thread: it logs every byte in and out with a
monotonic timestamp, decodes the stream with the shared wire codec, matches replies to the one
request in flight by sequence number and keeps events for whoever waits for them. Every wait
has a deadline; a vanished port makes every call raise `DeviceGone` until `reconnect()`.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable, Collection, Iterable, Mapping
from dataclasses import dataclass, field

import serial

from rig.core.errors import (
    DeviceGone,
    DeviceRefused,
    DeviceTimeout,
    GarbledReply,
    ParameterError,
    RigError,
)
from rig.drivers.codec import CommandSpec, HostCodec
from rig.drivers.connection import Connection, SerialLike
from rig.drivers.inbox import EventFilter, EventInbox, ReceivedEvent
from rig.drivers.traffic import TrafficLog, TrafficRecord
from rig.drivers.wire import ErrorReply, Event, Garbled, Item, Reply

log = logging.getLogger(__name__)

BAUDRATE = 115200
SAFE_TO_REPEAT = frozenset({"ID", "STATUS", "CFG", "CLOCK", "ENV"})  # queries without effects

__all__ = [
    "SAFE_TO_REPEAT",
    "LineTransport",
    "ReceivedEvent",
    "SerialLike",
    "TrafficLog",
    "TrafficRecord",
    "open_port",
]


def open_port(
    url: str,
    *,
    device: str = "port",
    baudrate: int = BAUDRATE,
    timeout: float = 0.05,
    write_timeout: float = 1.0,
    parity: str = "N",
    stopbits: int = 1,
    exclusive: bool | None = None,
) -> SerialLike:
    """Open a port by path or URL (8 data bits); any failure is a `DeviceGone` naming the device and URL."""
    try:
        return serial.serial_for_url(
            url,
            baudrate=baudrate,
            timeout=timeout,
            write_timeout=write_timeout,
            parity=parity,
            stopbits=stopbits,
            exclusive=exclusive,
        )
    except RigError:
        raise  # ours already names its cause (e.g. a simulator's bad scene file)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise DeviceGone(device, f"cannot open {url!r}: {exc}") from exc


@dataclass
class _Pending:
    seq: int
    verb: str
    done: threading.Event = field(default_factory=threading.Event)
    item: Item | None = None
    lost: str | None = None  # why the port went away while waiting


class _Lost(DeviceGone):
    """The port went away during this very request (so a query may be retried after reconnect)."""


class LineTransport:
    """One device's port: request/reply by sequence number, events by name, a full traffic log."""

    def __init__(
        self,
        device: str,
        target: str | SerialLike,
        specs: Mapping[str, CommandSpec],
        *,
        baudrate: int = BAUDRATE,
        read_timeout_s: float = 0.05,
        reply_timeout_s: float = 0.5,
        safe_to_repeat: Collection[str] = SAFE_TO_REPEAT,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
        reopen: Callable[[], SerialLike] | None = None,
    ) -> None:
        self.device = device
        self.url = target if isinstance(target, str) else getattr(target, "port", None) or repr(target)
        self.reply_timeout_s = reply_timeout_s
        self.safe_to_repeat = frozenset(safe_to_repeat)
        self.traffic = TrafficLog(on_traffic)
        self._inbox = EventInbox()
        self._read_timeout_s = read_timeout_s
        self._codec = HostCodec(specs)
        self._lock = threading.Lock()  # guards everything below
        self._request_lock = threading.Lock()  # one command in flight at a time
        self._pending: _Pending | None = None
        self._gone: str | None = None
        self._closed = False
        self._garbled: list[tuple[float, Garbled]] = []
        self._stale: list[tuple[float, Reply | ErrorReply]] = []
        if isinstance(target, str):
            url = target
            self._reopen = reopen or (
                lambda: open_port(url, device=device, baudrate=baudrate, timeout=read_timeout_s)
            )
            port = open_port(url, device=device, baudrate=baudrate, timeout=read_timeout_s)
        else:
            self._reopen = reopen or self._reopen_same
            port = target
        self._conn = self._connect(port)
        self._conn.start()

    # -- requests ---------------------------------------------------------------------------

    def request(self, verb: str, *args: object, timeout_s: float | None = None) -> Reply:
        """Send one command and return its reply; raises DeviceRefused, GarbledReply,
        DeviceTimeout or DeviceGone. A query safe to repeat is retried once if the port
        vanished during it and a reconnect succeeds; a command with effects never is."""
        timeout = self.reply_timeout_s if timeout_s is None else timeout_s
        try:
            return self._exchange(verb, args, timeout)
        except _Lost:
            if verb not in self.safe_to_repeat:
                raise
            log.warning("%s: port lost during %s; reconnecting and retrying once", self.device, verb)
            self.reconnect()
            return self._exchange(verb, args, timeout)

    def _exchange(self, verb: str, args: tuple[object, ...], timeout: float) -> Reply:
        if not self._request_lock.acquire(timeout=timeout + self.reply_timeout_s):
            raise DeviceTimeout(self.device, f"{verb}: another command is still waiting for its reply")
        try:
            with self._lock:
                self._raise_if_gone()
                try:
                    seq, frame = self._codec.command(verb, *args)
                except ValueError as exc:
                    raise ParameterError(f"{self.device} {verb}", args, str(exc)) from None
                pending = self._pending = _Pending(seq, verb)
                conn = self._conn
            try:
                conn.write(frame)
            except OSError as exc:  # serial.SerialException is an OSError
                self._lost(conn, f"write failed: {exc}")
            except BaseException:
                self._forget(pending)
                raise
            pending.done.wait(timeout)
            self._forget(pending)
            return self._outcome(pending, timeout)
        finally:
            self._request_lock.release()

    def _forget(self, pending: _Pending) -> None:
        with self._lock:
            if self._pending is pending:
                self._pending = None  # a reply arriving from now on is stale

    def _outcome(self, pending: _Pending, timeout: float) -> Reply:
        verb, item = pending.verb, pending.item
        if self._closed:
            raise DeviceGone(self.device, f"{verb}: port {self.url} was closed")
        if pending.lost is not None:
            raise _Lost(self.device, f"{verb}: port {self.url} lost ({pending.lost})")
        if isinstance(item, Reply):
            return item
        if isinstance(item, ErrorReply):
            raise DeviceRefused(self.device, verb, item.code, item.text)
        if isinstance(item, Garbled):
            raise GarbledReply(self.device, f"garbled reply to {verb}: {item.reason} ({item.raw!r})")
        raise DeviceTimeout(self.device, f"no reply to {verb} (seq {pending.seq}) within {timeout:g} s")

    # -- events ---------------------------------------------------------------------------

    def next_event(
        self, names: str | Iterable[str], timeout_s: float, predicate: EventFilter | None = None
    ) -> ReceivedEvent:
        """The oldest kept event with one of `names` (those failing `predicate` are discarded),
        with its receive time; DeviceTimeout after `timeout_s`, DeviceGone if the port goes."""
        rec = self._inbox.take(names, timeout_s, predicate, check=self._check_alive)
        if rec is None:
            wanted = names if isinstance(names, str) else "/".join(names)
            raise DeviceTimeout(self.device, f"no {wanted} event within {timeout_s:g} s")
        return rec

    def wait_event(
        self, names: str | Iterable[str], timeout_s: float, predicate: EventFilter | None = None
    ) -> Event:
        """Like `next_event`, without the receive time."""
        return self.next_event(names, timeout_s, predicate).event

    def clear_events(self, names: str | Iterable[str] | None = None) -> int:
        """Forget kept events (of `names`, or all); returns how many. They stay in the traffic log."""
        return self._inbox.clear(names)

    @property
    def all_events(self) -> queue.Queue[ReceivedEvent]:
        """Every event received (bounded: the oldest is dropped when nobody reads it)."""
        return self._inbox.all_events

    def _check_alive(self) -> None:
        with self._lock:
            self._raise_if_gone()

    # -- diagnostics ------------------------------------------------------------------------

    @property
    def gone(self) -> str | None:
        """Why the port is unusable (None while it works)."""
        with self._lock:
            return "closed" if self._closed else self._gone

    def garbled(self) -> list[tuple[float, Garbled]]:
        """Every garbled line received, with its receive time."""
        with self._lock:
            return list(self._garbled)

    def stale(self) -> list[tuple[float, Reply | ErrorReply]]:
        """Replies that matched no request in flight (late or duplicate), dropped."""
        with self._lock:
            return list(self._stale)

    # -- the connection's callbacks ---------------------------------------------------------

    def _connect(self, port: SerialLike) -> Connection:
        return Connection(self.device, port, self.traffic, self._dispatch, self._lost, self._read_timeout_s)

    def _dispatch(self, conn: Connection, item: Item, t: float) -> None:
        with self._lock:
            if conn is not self._conn:
                return
            if not isinstance(item, Event):
                self._answer(item, t)
                return
        self._inbox.put(item, t)  # outside our lock: a waiter holds the inbox's and then takes ours

    def _answer(self, item: Item, t: float) -> None:
        """A reply, error reply or garbled line: it resolves the request in flight, if it can."""
        pending = self._pending
        if isinstance(item, Garbled):
            self._garbled.append((t, item))
            log.warning("%s: garbled line: %s %r", self.device, item.reason, item.raw)
            if pending is not None:  # it may have been the reply: the request cannot trust any other
                self._resolve(pending, item)
        elif isinstance(item, Reply | ErrorReply):
            if pending is not None and item.seq == pending.seq:
                self._resolve(pending, item)
            else:
                self._stale.append((t, item))
                log.warning("%s: stale reply dropped: %r", self.device, item)

    def _resolve(self, pending: _Pending, item: Item) -> None:
        pending.item = item
        self._pending = None
        pending.done.set()

    def _lost(self, conn: Connection, reason: str) -> None:
        with self._lock:
            if conn is not self._conn:
                return
            if self._gone is None:
                self._gone = reason
                log.error("%s: port %s lost: %s", self.device, self.url, reason)
            pending, self._pending = self._pending, None
            if pending is not None:
                pending.lost = reason
                pending.done.set()
        self._inbox.wake()

    def _raise_if_gone(self) -> None:
        if self._closed:
            raise DeviceGone(self.device, f"port {self.url} is closed")
        if self._gone is not None:
            raise DeviceGone(
                self.device,
                f"port {self.url} lost ({self._gone}); check its cable and power, "
                "then resume the run or try again",
            )

    # -- lifecycle --------------------------------------------------------------------------

    def _reopen_same(self) -> SerialLike:
        port = self._conn.port
        opener = getattr(port, "open", None)
        if opener is None:
            raise DeviceGone(self.device, f"cannot reopen {self.url}: this kind of port cannot be reopened")
        opener()
        return port

    def reconnect(self) -> None:
        """Close the port and open it again (the same URL); DeviceGone if that fails."""
        with self._request_lock:
            with self._lock:
                if self._closed:
                    raise DeviceGone(self.device, f"port {self.url} is closed")
                self._gone = "reconnecting"
                old = self._conn
            self._inbox.wake()
            old.close()
            try:
                port = self._reopen()
            except (DeviceGone, OSError, ValueError) as exc:
                with self._lock:
                    self._gone = f"reconnect failed: {exc}"
                if isinstance(exc, DeviceGone):
                    raise
                raise DeviceGone(self.device, f"cannot reopen {self.url}: {exc}") from exc
            conn = self._connect(port)
            with self._lock:
                closed = self._closed
                self._conn, self._gone = conn, None
            if closed:  # close() came while reopening
                conn.close()
                raise DeviceGone(self.device, f"port {self.url} was closed while reconnecting")
            conn.start()
            log.info("%s: reconnected to %s", self.device, self.url)

    def close(self) -> None:
        """Stop the reader thread and close the port; later calls raise DeviceGone."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            pending, self._pending = self._pending, None
            if pending is not None:
                pending.lost = "closed"
                pending.done.set()
        self._inbox.wake()
        self._conn.close()

    def __enter__(self) -> LineTransport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

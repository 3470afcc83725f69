"""Serve one simulated rig out of process: each device on a pty or a TCP port of 127.0.0.1.

`python -m rig.simulators.serve --scene lab --kind tcp` prints one line per device, `<name> <url>`
(`cannon socket://127.0.0.1:40123`, or `gates /dev/pts/7` for a pty), and runs until interrupted.
Before it prints them it fires one dummy shot in a throwaway world of the scene (rig.simulators.warmup),
so that the first FIRE is answered as fast as any later one (`--no-warm` skips this).
One thread, one selector. The server forwards a device's output as soon as it is queued, so the
virtual clock runs ahead to the last consequence queued (nothing sleeps). An unplug fault closes
the TCP connection (a new connection plugs the device back in) or replaces the pty with a new one,
whose path is printed on a new line, as a USB adapter re-enumerates.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import selectors
import socket
import sys
import threading
import tty
from typing import TextIO

from rig.simulators.device import SimDevice, Unplugged
from rig.simulators.scene import Scene
from rig.simulators.warmup import warm_up
from rig.simulators.world import SimWorld

POLL_S = 0.05  # how often the loop looks at the stop event


class _Endpoint:
    """One device's end: a listening socket and its client, or a pty master."""

    def __init__(self, device: SimDevice, kind: str, host: str, port: int) -> None:
        self.device, self.kind = device, kind
        self.listener: socket.socket | None = None
        self.conn: socket.socket | None = None
        self.master = self.slave = -1
        self.pending = b""
        if kind == "tcp":
            self.listener = socket.create_server((host, port))
            self.listener.setblocking(False)
        else:
            self._open_pty()

    def _open_pty(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)  # no echo, no line discipline: bytes pass as they are
        os.set_blocking(self.master, False)

    @property
    def url(self) -> str:
        """Where a host opens this device."""
        if self.listener is not None:
            addr, port = self.listener.getsockname()[:2]
            return f"socket://{addr}:{port}"
        return os.ttyname(self.slave)

    def readable(self) -> list[object]:
        """The file objects the selector should watch."""
        if self.kind == "tcp":
            return [x for x in (self.listener, self.conn) if x is not None]
        return [self.master]

    def take_input(self, source: object) -> None:
        """Accept a connection or pass received bytes to the device."""
        if source is self.listener and self.listener is not None:
            conn, _ = self.listener.accept()
            self.drop_client()
            conn.setblocking(False)
            self.conn = conn
            self.device.replug()  # a new connection is a freshly opened port
            return
        try:
            data = self._recv()
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            if self.kind == "tcp":
                self.drop_client()
            return  # a pty with no reader attached: nothing to do
        try:
            self.device.write(data)
        except Unplugged:
            self.unplug()

    def flush(self) -> bool:
        """Send what the device has queued; False if the device was unplugged (endpoint renewed)."""
        if self.kind == "tcp" and self.conn is None:
            return True  # nobody connected: output waits in the device
        try:
            self.pending += self.device.read()
        except Unplugged:
            self.unplug()
            return False
        if self.pending:
            try:
                sent = self._send(self.pending)
            except (BlockingIOError, InterruptedError):
                sent = 0
            except OSError:
                sent = len(self.pending)  # the peer went away: drop it, as a serial line would
            self.pending = self.pending[sent:]
        return True

    def _recv(self) -> bytes:
        return self.conn.recv(4096) if self.conn is not None else os.read(self.master, 4096)

    def _send(self, data: bytes) -> int:
        return self.conn.send(data) if self.conn is not None else os.write(self.master, data)

    def unplug(self) -> None:
        """The device dropped off: cut the connection, or swap the pty for a new one."""
        self.pending = b""
        if self.kind == "tcp":
            self.drop_client()
        else:
            self.close()
            self._open_pty()
            self.device.replug()

    def drop_client(self) -> None:
        """Close the TCP client, if any."""
        if self.conn is not None:
            with contextlib.suppress(OSError):
                self.conn.close()
            self.conn = None

    def close(self) -> None:
        """Release every descriptor."""
        self.drop_client()
        if self.listener is not None:
            self.listener.close()
        for fd in (self.master, self.slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self.master = self.slave = -1


def serve(
    scene: Scene | str,
    kind: str = "pty",
    host: str = "127.0.0.1",
    base_port: int = 0,
    stop: threading.Event | None = None,
    out: TextIO | None = None,
    warm: bool = True,
) -> None:
    """Expose the devices of one world until interrupted or `stop` is set; print `<name> <url>` lines.

    With `warm` (the default) the physics is loaded and exercised before the first line is printed.
    """
    if kind not in ("pty", "tcp"):
        raise ValueError(f"kind must be 'pty' or 'tcp', not {kind!r}")
    out = out if out is not None else sys.stdout
    stop = stop if stop is not None else threading.Event()
    world = SimWorld(scene if isinstance(scene, Scene) else Scene.load(scene))
    endpoints: list[_Endpoint] = []
    selector = selectors.DefaultSelector()
    try:
        if warm:
            warm_up(world.scene)
        for i, (name, device) in enumerate(world.devices.items()):
            endpoints.append(_Endpoint(device, kind, host, base_port + i if base_port else 0))
            print(f"{name} {endpoints[-1].url}", file=out, flush=True)
        _loop(endpoints, selector, stop, out)
    except KeyboardInterrupt:
        pass
    finally:
        selector.close()
        for endpoint in endpoints:
            endpoint.close()


def _loop(
    endpoints: list[_Endpoint], selector: selectors.BaseSelector, stop: threading.Event, out: TextIO
) -> None:
    watched: dict[object, _Endpoint] = {}
    while not stop.is_set():
        wanted = {obj: ep for ep in endpoints for obj in ep.readable()}
        for obj in set(watched) - set(wanted):
            with contextlib.suppress(KeyError, ValueError):
                selector.unregister(obj)  # type: ignore[arg-type]
        for obj in set(wanted) - set(watched):
            selector.register(obj, selectors.EVENT_READ)  # type: ignore[arg-type]
        watched = wanted
        for key, _ in selector.select(POLL_S):
            watched[key.fileobj].take_input(key.fileobj)
        # A command to one device queues events on the others (FIRE -> beam breaks), so flush all.
        for ep in endpoints:
            if not ep.flush() and ep.kind == "pty":
                print(f"{ep.device.name} {ep.url}", file=out, flush=True)


def main(argv: list[str] | None = None) -> int:
    """Command line: serve a scene's devices until Ctrl-C."""
    parser = argparse.ArgumentParser(prog="python -m rig.simulators.serve", description=__doc__)
    parser.add_argument("--scene", default="ideal", help="built-in scene name or path to a scene TOML")
    parser.add_argument("--kind", choices=("pty", "tcp"), default="pty")
    parser.add_argument("--host", default="127.0.0.1")
    parser.add_argument("--base-port", type=int, default=0, help="cannon on this port, gates +1, clamp +2")
    parser.add_argument(
        "--no-warm",
        action="store_true",
        help="announce the ports at once (the first FIRE then loads the physics)",
    )
    args = parser.parse_args(argv)
    serve(args.scene, kind=args.kind, host=args.host, base_port=args.base_port, warm=not args.no_warm)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""A text-line instrument on a local TCP port: one client at a time, each line handled in order.

A twin gives `handle(line) -> reply | None`; the server answers each reply as one "\\n"-ended line.
A new connection replaces the old one (a replug: the instrument keeps its state). `None` from
`handle` sends nothing (a command, or a query the instrument leaves unanswered).
"""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Callable


class LineServer:
    """Serves `handle` on a TCP port of `host` in daemon threads; `start` gives the port."""

    def __init__(
        self, handle: Callable[[str], str | None], name: str, drops: Callable[[str], bool] | None = None
    ) -> None:
        self.handle = handle
        self.name = name
        self.drops = drops  # a fault: the connection goes when this says so of a line
        self._server: socket.socket | None = None
        self._conn: socket.socket | None = None
        self._lock = threading.Lock()

    def start(self, host: str = "127.0.0.1", port: int = 0) -> int:
        """Listen on `host:port` (0: any free port); the port listened on."""
        server = socket.create_server((host, port))
        self._server = server
        threading.Thread(target=self._accept, name=f"{self.name}-accept", daemon=True).start()
        return int(server.getsockname()[1])

    def close(self) -> None:
        """Stop listening and hang up."""
        if self._server is not None:
            with contextlib.suppress(OSError):
                self._server.shutdown(socket.SHUT_RDWR)  # wakes the accept (close alone does not)
            with contextlib.suppress(OSError):
                self._server.close()
        self.hang_up()

    def hang_up(self, only: socket.socket | None = None) -> None:
        """Close the client's connection (`only`: if it is still that one)."""
        with self._lock:
            conn = self._conn
            if conn is None or (only is not None and conn is not only):
                return
            self._conn = None
        with contextlib.suppress(OSError):
            conn.shutdown(socket.SHUT_RDWR)
        with contextlib.suppress(OSError):
            conn.close()

    def _accept(self) -> None:
        server = self._server
        assert server is not None
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return  # closed
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.hang_up()
            with self._lock:
                self._conn = conn
            threading.Thread(target=self._serve, args=(conn,), name=self.name, daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        buffer = b""
        while True:
            try:
                data = conn.recv(4096)
            except OSError:
                data = b""
            if not data:
                self.hang_up(conn)
                return
            buffer += data
            while b"\n" in buffer:
                raw, buffer = buffer.split(b"\n", 1)
                line = raw.decode("ascii", errors="replace").strip()
                if line and self.drops is not None and self.drops(line):
                    self.hang_up(conn)
                    return
                reply = self.handle(line) if line else None
                if reply is None:
                    continue
                try:
                    conn.sendall(reply.encode("latin-1", errors="replace") + b"\n")
                except OSError:
                    self.hang_up(conn)
                    return

"""What every device driver shares: a transport, identification, typed parsing, lifecycle."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, ClassVar, Self, TypeVar

from rig.core.devices import InstrumentIdentity
from rig.core.errors import GarbledReply
from rig.drivers.codec import CommandSpec
from rig.drivers.registry import DriverContext
from rig.drivers.transport import LineTransport, SerialLike, TrafficRecord
from rig.drivers.wire import Event, Reply

M = TypeVar("M")
R = TypeVar("R")


Identity = InstrumentIdentity  # what a device says it is (the ID command)


class LineDriver:
    """Base of the device drivers: one `LineTransport` to one device, opened by URL or port."""

    NAME: ClassVar[str] = "device"
    SPECS: ClassVar[Mapping[str, CommandSpec]] = {}
    OPTIONS: ClassVar[Mapping[str, type]] = {}  # the [devices.KIND] options a subclass takes (by type)

    def __init__(
        self,
        port: str | SerialLike,
        *,
        name: str | None = None,
        reply_timeout_s: float = 0.5,
        on_traffic: Callable[[TrafficRecord], None] | None = None,
        reopen: Callable[[], SerialLike] | None = None,
    ) -> None:
        self.name = name or self.NAME
        self.transport = LineTransport(
            self.name, port, self.SPECS, reply_timeout_s=reply_timeout_s, on_traffic=on_traffic, reopen=reopen
        )

    @classmethod
    def from_context(cls, context: DriverContext) -> Self:
        """The `rig-line` driver of a rig config: our line protocol at `address` (options: OPTIONS)."""
        context.only_options(cls.OPTIONS)
        return cls(
            context.address,
            name=context.kind,
            reply_timeout_s=context.timeouts.reply_s,
            on_traffic=context.on_traffic,
            **cls._context_kwargs(context),
        )

    @classmethod
    def _context_kwargs(cls, context: DriverContext) -> dict[str, Any]:
        """A subclass's own constructor arguments taken from the rig config."""
        return {}

    def identify(self) -> Identity:
        """Model, firmware version and serial number."""
        reply = self.transport.request("ID")
        return self._parse(
            lambda r: Identity(r.named()["MODEL"], r.named()["FW"], r.named()["SN"]), reply, "ID reply"
        )

    def reconnect(self) -> None:
        """Re-open the port after it vanished (DeviceGone until then)."""
        self.transport.reconnect()

    def close(self) -> None:
        """Stop the reader thread and close the port."""
        self.transport.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _parse(self, parser: Callable[[M], R], message: M, what: str) -> R:
        """Run a codec parser; a missing or malformed field becomes a GarbledReply naming it."""
        try:
            return parser(message)
        except (ValueError, KeyError) as exc:
            missing = f"lacks field {exc.args[0]}" if isinstance(exc, KeyError) else str(exc)
            raise GarbledReply(self.name, f"{what}: {missing} in {_show(message)}") from None


def _show(message: object) -> str:
    if isinstance(message, Reply):
        return "OK " + " ".join(message.fields)
    if isinstance(message, Event):
        return f"! {message.name} " + " ".join(message.fields)
    return repr(message)

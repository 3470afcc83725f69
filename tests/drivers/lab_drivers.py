"""Factories a lab might write, named by import path in tests/drivers/test_registry.py."""

from __future__ import annotations

from typing import Any

from rig.drivers.gates.driver import GatesDriver
from rig.drivers.registry import DriverContext

OPENED: list[str] = []
CLOSED: list[str] = []


class CountingGates(GatesDriver):
    """Our own gates driver, opened by a lab's factory that takes one option."""

    def close(self) -> None:
        CLOSED.append(self.name)
        super().close()


def counting_gates(context: DriverContext) -> CountingGates:
    """A lab's factory: one option of its own (`label`, text)."""
    options = context.only_options({"label": str})
    OPENED.append(str(options.get("label", "")))
    return CountingGates(
        context.address,
        name=context.kind,
        reply_timeout_s=context.timeouts.reply_s,
        on_traffic=context.on_traffic,
    )


class HalfAGates:
    """Not a gates driver: it has no crossings() or self_test()."""

    def __init__(self) -> None:
        self.closed = False

    def config(self) -> Any:
        return None

    def close(self) -> None:
        CLOSED.append("half")


def half_a_gates(context: DriverContext) -> HalfAGates:
    """A factory whose device lacks most of the interface."""
    return HalfAGates()


NOT_CALLABLE = 3


def raising_factory(context: DriverContext) -> None:
    """A lab's factory with a bug."""
    _ = 1 / 0

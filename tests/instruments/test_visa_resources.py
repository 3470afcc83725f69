"""VISA resource strings beyond the TCP socket: each interface the counter may sit on is taken, and
one that cannot be opened here (no USB or GPIB stack, no such port, not a resource string at all) is
one line naming the resource and the cause, never a traceback or a second line."""

from __future__ import annotations

import pytest

from rig.core.errors import DeviceGone
from rig.drivers.registry import DriverContext
from rig.drivers.scpi.counter import ScpiCounterGates
from rig.drivers.scpi.visa import resource_kind


@pytest.mark.parametrize(
    ("resource", "kind"),
    [
        ("TCPIP0::192.168.1.7::5025::SOCKET", "TCPIP"),
        ("tcpip::counter.lab::inst0::INSTR", "TCPIP"),
        ("USB0::0x0957::0x1907::MY12345678::INSTR", "USB"),
        ("GPIB0::3::INSTR", "GPIB"),
        ("ASRL/dev/ttyUSB0::INSTR", "ASRL"),
        ("socket://127.0.0.1:5025", None),
        ("USB", None),
        ("", None),
    ],
)
def test_the_interface_of_a_resource_string(resource: str, kind: str | None) -> None:
    assert resource_kind(resource) == kind


@pytest.mark.parametrize(
    ("resource", "said"),
    [
        ("USB0::0x0957::0x1907::MY12345678::INSTR", "USB0::0x0957::0x1907::MY12345678::INSTR"),
        ("GPIB0::3::INSTR", "GPIB0::3::INSTR"),
        ("ASRL/dev/no-such-counter::INSTR", "no-such-counter"),
        ("counter-on-the-bench", "is not a VISA resource string"),
    ],
)
def test_a_resource_that_cannot_be_opened_is_one_line(resource: str, said: str) -> None:
    context = DriverContext(kind="gates", name="gates", address=resource, options={})
    with pytest.raises(DeviceGone) as info:
        ScpiCounterGates.from_context(context)
    text = str(info.value)
    assert said in text and "\n" not in text and text.startswith("gates: ")

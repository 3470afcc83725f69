"""The simulated rig's equipment register: one item for every role (rig.core.config.EQUIPMENT_ROLES).

A sample of what a lab lists. The devices' items give no serial number: a simulated device may be
served by another driver's twin (rig sim serve --twin, the tests), each reporting its own, and the
run records what each device reports anyway. The dates are counted from the day the config is
made, so the sample stays in date: each item calibrated CALIBRATED_DAYS_AGO days ago, due a year
after that.
"""

from __future__ import annotations

from datetime import date, timedelta
from typing import Any

CALIBRATED_DAYS_AGO = 90
INTERVAL_DAYS = 365  # [assumed] a yearly calibration interval for every item

# (name, role, device, serial, certificate); the certificates and serials are made up
SAMPLE: tuple[tuple[str, str, str | None, str | None, str], ...] = (
    ("air cannon pressure controller", "cannon", "cannon", None, "SIM-CAL-CANNON"),
    ("light gates and counter", "gates", "gates", None, "SIM-CAL-GATES"),
    ("pivot clamp and swing sensor", "clamp", "clamp", None, "SIM-CAL-CLAMP"),
    ("steel rule for the gate positions", "gate-gauge", None, "SIM-R-300", "SIM-CAL-RULE"),
    ("pendulum period timer", "pendulum-timer", None, "SIM-T-01", "SIM-CAL-TIMER"),
    ("bench scale", "scale", None, "SIM-S-0042", "SIM-CAL-SCALE"),
    ("lab thermometer", "thermometer", None, "SIM-TH-7", "SIM-CAL-TEMP"),
    ("lab hygrometer", "hygrometer", None, "SIM-HY-7", "SIM-CAL-RH"),
    ("lab barometer", "barometer", None, "SIM-BA-3", "SIM-CAL-BARO"),
    ("ball compression tester", "compression-tester", None, "SIM-BC-12", "SIM-CAL-COMP"),
    ("barrel compression tester", "barrel-compression-tester", None, "SIM-B001", "SIM-CAL-BARREL"),
)


def sample_register(today: date) -> list[dict[str, Any]]:
    """The sample register as rig-config [[equipment]] tables, in date on `today`."""
    calibrated = today - timedelta(days=CALIBRATED_DAYS_AGO)
    due = calibrated + timedelta(days=INTERVAL_DAYS)
    return [
        {
            "name": name,
            "role": role,
            **({"device": device} if device else {}),
            **({"serial": serial} if serial else {}),
            "certificate": certificate,
            "calibrated": calibrated,
            "due": due,
        }
        for name, role, device, serial, certificate in SAMPLE
    ]

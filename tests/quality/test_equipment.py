"""The equipment register: roles, `rig equipment` (due dates, exit codes), the simulated rig's sample
register, and the certificate's list of the equipment a result depended on."""

from __future__ import annotations

import io
import json
from contextlib import redirect_stderr, redirect_stdout
from datetime import date, timedelta
from pathlib import Path
from typing import get_args

import pytest

from rig.certification import certify
from rig.cli import main
from rig.core.config import EQUIPMENT_ROLES, Equipment, RigConfig, Role
from rig.core.errors import ConfigError
from rig.instruments import BALL_ROLES, BAT_ROLES, SHOT_ROLES, roles_for, today_utc, uncovered
from rig.protocols.abi import abi
from rig.protocols.steps import plan_name
from rig.report.certificate import render
from rig.report.record import run_record
from rig.session import sim_config
from rig.store import Store
from tests.instruments.test_identity import BAT, _procedure

PORTS = '[ports]\ncannon = "/dev/null"\ngates = "/dev/null"\nclamp = "/dev/null"\n'


def rig(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(list(argv))
    return code, out.getvalue(), err.getvalue()


def item(name: str, role: str, due: date | None, device: str | None = None) -> str:
    lines = ["[[equipment]]", f'name = "{name}"', f'role = "{role}"']
    if device:
        lines.append(f'device = "{device}"')
    if due is not None:
        lines += [f"calibrated = {due - timedelta(days=365)}", f"due = {due}"]
    return "\n".join(lines) + "\n"


def config(tmp_path: Path, *items: str) -> Path:
    path = tmp_path / "rig.toml"
    path.write_text(PORTS + "".join(items))
    return path


def test_the_vocabulary_and_the_role_type_agree() -> None:
    assert tuple(get_args(Role)) == tuple(EQUIPMENT_ROLES)
    # the issue's list: the scale, thermometer and hygrometer, the pendulum timer, the gate positions'
    # measuring tool, the ball compression tester, besides the three devices
    needed = {
        "cannon",
        "gates",
        "clamp",
        "scale",
        "thermometer",
        "hygrometer",
        "pendulum-timer",
        "gate-gauge",
        "compression-tester",
    }
    assert needed <= set(EQUIPMENT_ROLES)


def test_which_roles_a_procedure_depends_on() -> None:
    assert roles_for({"standard": "bbcor"}) == BAT_ROLES
    assert roles_for({"test": "ball-cor"}) == BALL_ROLES
    assert roles_for({"name": "one shot"}) == roles_for(None) == SHOT_ROLES
    assert {"pendulum-timer", "scale", "gate-gauge"} <= set(
        BAT_ROLES
    ) and "compression-tester" not in BAT_ROLES
    assert "compression-tester" in BALL_ROLES and "pendulum-timer" not in BALL_ROLES
    # an accelerated break-in also squeezes the barrel: its record names the ABI's plan
    assert roles_for({"standard": "bbcor"}, plan_name(abi)) == (*BAT_ROLES, "barrel-compression-tester")
    assert roles_for({"standard": "bbcor"}, "labs.own.plan") == BAT_ROLES
    assert set(BAT_ROLES) | set(BALL_ROLES) | {"barrel-compression-tester"} == set(EQUIPMENT_ROLES)
    assert uncovered([{"device": "gates"}, {"role": "scale"}], ("gates", "scale", "barometer")) == [
        "barometer"
    ]


def test_a_role_that_is_not_its_devices_is_refused() -> None:
    with pytest.raises(ValueError, match="role 'scale' is not its device's"):
        Equipment(name="x", device="gates", role="scale")
    assert Equipment(name="x", device="gates").purpose == "gates"
    assert Equipment(name="x", role="scale").purpose == "scale"


def test_the_simulated_rig_carries_a_sample_register_with_every_role_in_date() -> None:
    config_ = sim_config("lab")
    assert sorted(e.purpose for e in config_.equipment) == sorted(EQUIPMENT_ROLES)
    assert all(e.due is not None and e.due > today_utc() for e in config_.equipment)
    code, out, err = rig("equipment", "--sim", "lab", "--json")
    got = json.loads(out)
    assert code == 0 and got["exit_status"] == 0, err
    assert got["uncovered_roles"] == [] and got["past_due"] == got["due_within"] == []
    for i in got["items"]:  # days left by the calendar, counted here from the dates printed
        assert i["days_left"] == (date.fromisoformat(i["due"]) - date.fromisoformat(got["day"])).days


def test_the_example_rig_config_covers_every_role() -> None:
    example = RigConfig.load(Path(__file__).resolve().parents[2] / "protocols" / "examples" / "rig.toml")
    assert sorted(e.purpose for e in example.equipment) == sorted(EQUIPMENT_ROLES)


def test_what_falls_due_within_days_and_what_is_past_due(tmp_path: Path) -> None:
    today = today_utc()
    path = config(
        tmp_path,
        item("gate counter", "gates", today + timedelta(days=10), device="gates"),
        item("scale", "scale", today + timedelta(days=30)),  # on the boundary: within 30 days
        item("thermometer", "thermometer", today + timedelta(days=31)),
        item("hygrometer", "hygrometer", today - timedelta(days=1)),
        item("rule", "gate-gauge", None),
    )
    code, out, _ = rig("equipment", "--config", str(path), "--json")
    got = json.loads(out)
    assert code == 1 == got["exit_status"]
    assert got["due_within"] == ["gate counter", "scale"]
    assert got["past_due"] == ["hygrometer"]
    assert [i["days_left"] for i in got["items"]] == [10, 30, 31, -1, None]
    assert [i["status"] for i in got["items"]] == ["in date", "in date", "in date", "past due", "no due date"]
    assert {g["role"] for g in got["uncovered_roles"]} == {
        "cannon",
        "clamp",
        "pendulum-timer",
        "barometer",
        "compression-tester",
    }
    code, out, _ = rig("equipment", "--config", str(path), "--within", "40")
    assert code == 1
    assert "due within 40 days: gate counter, scale, thermometer" in out and "past due: hygrometer" in out
    assert "HYGROMETER" not in out and "PAST DUE" in out
    assert "no item covers the role barometer: the lab's air pressure" in out


def test_a_full_register_in_date_exits_0(tmp_path: Path) -> None:
    later = today_utc() + timedelta(days=200)
    devices = ("cannon", "gates", "clamp")
    path = config(
        tmp_path, *(item(role, role, later, role if role in devices else None) for role in EQUIPMENT_ROLES)
    )
    code, out, _ = rig("equipment", "--config", str(path))
    assert code == 0 and "nothing falls due within 30 days" in out and "no item covers" not in out
    assert rig("equipment", "--config", str(path), "--within", "200")[0] == 1


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        ('[[equipment]]\nname = "x"\nrole = "sextant"\n', "role"),
        ('[[equipment]]\nname = "x"\ndevice = "gates"\nrole = "scale"\n', "is not its device's"),
        ('[[equipment]]\nname = "x"\ncalibrated = 2026-02-01\ndue = 2026-01-01\n', "before its calibration"),
    ],
)
def test_a_bad_register_is_one_line(tmp_path: Path, extra: str, needle: str) -> None:
    code, out, err = rig("equipment", "--config", str(config(tmp_path, extra)))
    assert code == 2 and out == "" and err.count("\n") == 1 and needle in err and "rig.toml" in err


@pytest.mark.parametrize("days", ["-1", "x", "99999"])
def test_a_bad_within_is_refused(days: str) -> None:
    with pytest.raises(SystemExit) as info, redirect_stderr(io.StringIO()):
        main(["equipment", "--sim", "--within", days])
    assert info.value.code == 2


def test_the_certificate_says_which_equipment_the_result_used_and_what_is_missing(tmp_path: Path) -> None:
    full = sim_config("ideal", bat=BAT)
    partial = full.model_copy(
        update={"equipment": tuple(e for e in full.equipment if e.purpose != "barometer")}
    )
    texts = {}
    with Store.open(tmp_path / "r.db") as store:
        for name, cfg in (("full", full), ("partial", partial)):
            out = certify(store, _procedure(), BAT, cfg)
            assert out.status == "finished"
            texts[name] = render(run_record(store, out.run_id), "md")
    section = texts["full"][texts["full"].index("## Instruments") : texts["full"].index("## Lab environment")]
    assert "| equipment | role | serial | certificate | calibrated | due | status | used |" in section
    assert "| bench scale | scale | SIM-S-0042 | SIM-CAL-SCALE |" in section
    assert section.count("| in date | yes |") == len(BAT_ROLES)
    assert "| ball compression tester | compression-tester |" in section and "| in date | no |" in section
    assert "The equipment register covers each of them." in section
    assert (
        "No item of the equipment register covers 1 of them: barometer (the lab's air pressure"
        in texts["partial"]
    )


def test_a_register_without_roles_keeps_the_old_table(tmp_path: Path) -> None:
    today = today_utc()
    old = Equipment(
        name="gate counter",
        device="gates",
        serial="SIM-G001",
        calibrated=today,
        due=today + timedelta(days=9),
    )
    with Store.open(tmp_path / "r.db") as store:
        out = certify(
            store, _procedure(), BAT, sim_config("ideal", bat=BAT).model_copy(update={"equipment": (old,)})
        )
        text = render(run_record(store, out.run_id), "md")
    assert "| equipment | device | serial | certificate | calibrated | due | status |" in text
    assert "| used |" not in text and "depends on" not in text


def test_no_config_is_one_line() -> None:
    code, _, err = rig("equipment")
    assert code == 2 and "give --sim [SCENE] or --config RIG.toml" in err


def test_config_error_type() -> None:
    with pytest.raises(ConfigError):
        RigConfig.from_dict(
            {"ports": {"cannon": "a", "gates": "b", "clamp": "c"}, "equipment": [{"name": "x", "role": "?"}]}
        )

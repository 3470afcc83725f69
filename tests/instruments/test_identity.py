"""What a run records of its instruments (rig.instruments): each device's identity, the equipment
list's calibrations, a refusal for an overdue one (unless accepted, who and why) or a wrong serial."""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import pytest

from rig.certification import Signoff, certify
from rig.core import events as ev
from rig.core.bat import BatSpec
from rig.core.config import Equipment, RigConfig
from rig.core.devices import InstrumentIdentity
from rig.core.errors import ConfigError
from rig.instruments import identify, today_utc
from rig.protocols.procedure import Procedure
from rig.report.certificate import render
from rig.report.record import run_record
from rig.session import RigSession, sim_config
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
BAT = BatSpec.load(ROOT / "protocols" / "examples" / "sample-bat.toml")


def _procedure() -> Procedure:
    """BBCOR with fewer shots: what is checked here is what surrounds them."""
    p = Procedure.load("bbcor")
    return p.model_copy(update={"hits": p.hits.model_copy(update={"valid_hits": 2})})


def _config(*equipment: Equipment) -> RigConfig:
    return sim_config("ideal", bat=BAT).model_copy(update={"equipment": equipment})


def _counter(days_left: int, serial: str = "SIM-G001") -> Equipment:
    today = today_utc()
    return Equipment(
        name="gate counter",
        device="gates",
        serial=serial,
        certificate="CAL-123",
        calibrated=today - timedelta(days=365 - days_left),
        due=today + timedelta(days=days_left),
    )


def test_a_run_records_what_each_device_said_it_is_right_after_it_started(tmp_path: Path) -> None:
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, _procedure(), BAT, _config(_counter(30)))
        kinds = [e.kind for e in store.entries(out.run_id)]
        (entry,) = [e for e in store.entries(out.run_id) if e.kind == ev.INSTRUMENTS_IDENTIFIED]
        record = run_record(store, out.run_id)
    assert out.status == "finished"
    assert kinds.index(ev.INSTRUMENTS_IDENTIFIED) == kinds.index(ev.RUN_STARTED) + 1
    assert kinds.index(ev.INSTRUMENTS_IDENTIFIED) < kinds.index(ev.SHOT_FIRED)
    devices = entry.payload["devices"]
    assert {k: d["model"] for k, d in devices.items()} == {
        "cannon": "SIM-CANNON",
        "gates": "SIM-GATES",
        "clamp": "SIM-CLAMP",
    }
    assert devices["gates"]["serial_number"] == "SIM-G001" and devices["gates"]["driver"] == "rig-line"
    assert all(d["simulated"] for d in devices.values())
    assert entry.payload["equipment"][0]["status"] == "in date" and entry.payload.get("override") is None
    text = render(record, "md")
    section = text[text.index("## Instruments") : text.index("## Lab environment")]
    assert "SIM-GATES (simulated)" in section and "SIM-G001" in section and "CAL-123" in section
    assert "in date" in section


def test_an_overdue_calibration_refuses_the_run_before_it_is_created(tmp_path: Path) -> None:
    with Store.open(tmp_path / "r.db") as store:
        with pytest.raises(ConfigError) as caught:
            certify(store, _procedure(), BAT, _config(_counter(-1)))
        assert store.runs() == []
    text = str(caught.value)
    assert "calibration past due: gate counter (due " in text and "--accept-overdue" in text
    assert "\n" not in text


def test_an_accepted_overdue_calibration_is_recorded_with_who_and_why(tmp_path: Path) -> None:
    accepted = Signoff("Q. Manager", "recalibration booked for Monday; counter checked against a reference")
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, _procedure(), BAT, _config(_counter(-3)), accept_overdue=accepted)
        (entry,) = [e for e in store.entries(out.run_id) if e.kind == ev.INSTRUMENTS_IDENTIFIED]
        text = render(run_record(store, out.run_id), "md")
    assert out.status == "finished"
    assert entry.payload["override"] == accepted.as_dict()
    assert entry.payload["equipment"][0]["status"] == "past due"
    assert "PAST DUE" in text and "(gate counter) accepted for this run by Q. Manager: recalibration" in text


def test_an_accepted_override_is_not_recorded_when_nothing_is_overdue(tmp_path: Path) -> None:
    with Store.open(tmp_path / "r.db") as store:
        out = certify(store, _procedure(), BAT, _config(_counter(10)), accept_overdue=Signoff("A", "B"))
        (entry,) = [e for e in store.entries(out.run_id) if e.kind == ev.INSTRUMENTS_IDENTIFIED]
    assert entry.payload.get("override") is None


def test_a_device_whose_serial_is_not_the_listed_one_refuses_the_run(tmp_path: Path) -> None:
    with Store.open(tmp_path / "r.db") as store:
        with pytest.raises(ConfigError, match=r"the gates device reports serial number SIM-G001, but"):
            certify(store, _procedure(), BAT, _config(_counter(30, serial="MY-0001")), accept_overdue=None)
        assert store.runs() == []


def test_a_resumed_run_is_identified_again_and_an_overdue_one_interrupts_it(tmp_path: Path) -> None:
    from rig.protocols.control import RunControl

    control = RunControl()
    control.abort()  # the run stops at its first checkpoint, resumable
    with Store.open(tmp_path / "r.db") as store:
        first = certify(store, _procedure(), BAT, _config(_counter(5)), control=control)
        assert first.status == "interrupted"
        again = certify(store, _procedure(), BAT, _config(_counter(-2)), run_id=first.run_id)
        assert again.status == "interrupted" and "calibration past due" in str(again.reason)
        done = certify(
            store,
            _procedure(),
            BAT,
            _config(_counter(-2)),
            run_id=first.run_id,
            accept_overdue=Signoff("A", "B"),
        )
        kinds = [e.kind for e in store.entries(first.run_id)]
    assert done.status == "finished"
    assert kinds.count(ev.INSTRUMENTS_IDENTIFIED) == 2  # the first session and the accepted resume


def test_a_ball_test_checks_its_instruments_as_a_certification_does(tmp_path: Path) -> None:
    from rig.balls import run_ball_test
    from tests.balls.test_ball_tests import lot, small

    p = small("ccor")
    config = sim_config("ideal", target=(p.target.kind, p.target.diameter_m)).model_copy(
        update={"equipment": (_counter(-1),)}
    )
    with Store.open(tmp_path / "b.db") as store:
        store.register_lot(lot())
        with pytest.raises(ConfigError, match=r"calibration past due: gate counter"):
            run_ball_test(store, p, lot(), config)
        assert store.runs() == []
        out = run_ball_test(store, p, lot(), config, accept_overdue=Signoff("Q. Manager", "checked"))
        (entry,) = [e for e in store.entries(out.run_id) if e.kind == ev.INSTRUMENTS_IDENTIFIED]
    assert out.status == "finished" and entry.payload["override"] == {"who": "Q. Manager", "why": "checked"}


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--accept-overdue"], "--accept-overdue needs --who NAME and --why TEXT"),
        (["--who", "A"], "--who and --why go with --accept-overdue"),
    ],
)
def test_the_ball_test_command_wants_who_and_why_with_an_override(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], says: str
) -> None:
    from rig.cli import main

    code = main(
        [
            "balls",
            "test",
            "--procedure",
            "ccor",
            "--lot",
            "X",
            "--sim",
            "ideal",
            "--db",
            str(tmp_path / "b.db"),
            *args,
        ]
    )
    assert code == 2 and says in capsys.readouterr().err


def test_an_override_of_an_earlier_session_stays_on_the_certificate(tmp_path: Path) -> None:
    """Session 1 ran with an overdue calibration accepted; the resumed session 2 is in date: the
    certificate still says who accepted what in session 1."""
    from rig.protocols.control import RunControl

    control = RunControl()
    control.abort()
    with Store.open(tmp_path / "r.db") as store:
        first = certify(
            store,
            _procedure(),
            BAT,
            _config(_counter(-2)),
            control=control,
            accept_overdue=Signoff("A. B", "why"),
        )
        done = certify(store, _procedure(), BAT, _config(_counter(30)), run_id=first.run_id)
        text = render(run_record(store, done.run_id), "md")
    assert done.status == "finished"
    assert "(gate counter) accepted for this run (session 1, from" in text and "by A. B: why" in text


class _SaysSerial:
    """Gates that say only a serial number (what identify() reads of a device)."""

    def __init__(self, serial: str) -> None:
        self.serial = serial

    def identify(self) -> InstrumentIdentity:
        return InstrumentIdentity("M", "1", self.serial)


def _refusals_with_gates_saying(serial: str, config: RigConfig) -> tuple[str, ...]:
    """rig.instruments.identify's refusals for `config`'s open rig whose gates report `serial`."""
    with RigSession.open(config) as session:
        real, session.gates = session.gates, _SaysSerial(serial)
        try:
            return identify(session, config, None).refusals
        finally:
            session.gates = real


def test_a_listed_serial_the_device_cannot_report_refuses_the_run() -> None:
    refusals = _refusals_with_gates_saying("", _config(_counter(30)))
    assert refusals and "reports none: its identity cannot be checked" in refusals[0]


def test_a_two_part_serial_matches_either_part() -> None:
    for serial, ok in (("VXM-1234", True), ("SENSOR-9", True), ("VXM-12", False)):
        refusals = _refusals_with_gates_saying("VXM-1234 / SENSOR-9", _config(_counter(30, serial=serial)))
        assert (not refusals) is ok, (serial, refusals)


def test_a_run_through_devices_marked_simulated_is_recorded_as_simulated(tmp_path: Path) -> None:
    """rig certify --end and signing read the recorded rig: a twin's device (marked simulated, a
    TCP address) makes the run simulated, as RigConfig.simulated says; a real address does not."""
    from rig.keys import recorded_simulated

    def started(devices: dict) -> bool:
        with Store.open(tmp_path / f"{len(list(tmp_path.iterdir()))}.db") as store:
            store.register_bat("b", {"id": "b"})
            run = store.create_run("bbcor", "b", {})
            store.append(run, ev.RUN_STARTED, {"procedure": {}, "bat": {}, "rig": {"devices": devices}})
            return recorded_simulated(store, run)

    twin = {"driver": "scpi-counter", "address": "TCPIP0::127.0.0.1::5025::SOCKET", "simulated": True}
    real = {"driver": "scpi-counter", "address": "TCPIP0::10.0.0.5::5025::SOCKET", "simulated": False}
    assert started({"gates": twin, "cannon": real, "clamp": real})
    assert not started({"gates": real, "cannon": real, "clamp": real})
    assert started({"gates": {**real, "address": "sim://gates?rig=x"}, "cannon": real, "clamp": real})


def test_the_python_api_takes_an_override_as_who_and_why(tmp_path: Path) -> None:
    import rig
    from rig.core.errors import ConfigError as Refused

    past_due = {"name": "gate counter", "device": "gates", "due": str(today_utc() - timedelta(days=1))}
    spec = rig.simulated("ideal", equipment=[past_due])
    with rig.open_store(tmp_path / "api.db") as store:
        with pytest.raises(Refused, match="calibration past due: gate counter"):
            rig.certify(
                bat=rig.Bat.load(ROOT / "protocols" / "examples" / "sample-bat.toml"),
                procedure="bbcor",
                rig=spec,
                store=store,
            )
        result = rig.certify(
            bat=rig.Bat.load(ROOT / "protocols" / "examples" / "sample-bat.toml"),
            procedure="bbcor",
            rig=spec,
            store=store,
            accept_overdue=("Q. Manager", "checked against a reference counter"),
        )
        (entry,) = store.entries(result.run_id, kinds=[ev.INSTRUMENTS_IDENTIFIED])
    assert result.finished
    assert entry.payload["override"] == {"who": "Q. Manager", "why": "checked against a reference counter"}

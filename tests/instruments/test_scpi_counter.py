"""The gates on an SCPI universal counter: codec, driver against the twin over TCP, certification."""

from __future__ import annotations

import base64
import itertools
import os
import socket
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.core.config import DeviceSpec, RigConfig
from rig.core.devices import GateCrossing
from rig.core.errors import ConfigError, DeviceGone, DeviceTimeout, GarbledReply, UnexpectedMessage
from rig.drivers.registry import DriverContext, open_device
from rig.drivers.scpi import counter_codec as codec
from rig.drivers.traffic import TrafficRecord
from rig.measure.speeds import shot_speeds, split_passes
from rig.protocols.procedure import Procedure
from rig.session import sim_config
from rig.simulators.instruments.scpi_counter import ScpiCounterTwin
from rig.simulators.scene import Scene
from rig.simulators.urlhandler import get_world, reset_worlds
from rig.simulators.world import SimWorld
from rig.store import Store
from tests.instruments.attempts import write_until_one_fails

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
POSITIONS = (0.75, 0.50, 0.25)
SETUP = codec.CounterSetup()


# -- codec ------------------------------------------------------------------------------------------
def closed_form_stamps(v_in: float, v_out: float, t0: float = 0.0123) -> list[float]:
    """A ball at v_in through gates 1, 2, 3 to the impact point, back at v_out through 3, 2, 1."""
    x1, x2, x3 = POSITIONS
    t_impact = t0 + x1 / v_in
    inbound = [t0 + (x1 - x) / v_in for x in POSITIONS]
    rebound = [t_impact + x / v_out for x in (x3, x2, x1)]
    return inbound + rebound


def test_closed_form_speeds_through_the_codec() -> None:
    reply = codec.format_stamps(closed_form_stamps(60.8, 25.4))
    crossings = codec.map_stamps(codec.parse_stamps(reply), SETUP)
    assert [c.gate for c in crossings] == [1, 2, 3, 3, 2, 1]
    cfg = SETUP.gate_config()
    speeds = shot_speeds(split_passes(crossings, cfg), POSITIONS, cfg)
    # 20 ps on 4.1 ms (inbound) and 9.8 ms (rebound): a few parts in 1e9
    assert speeds.inbound == pytest.approx(60.8, rel=1e-8)
    assert speeds.rebound == pytest.approx(25.4, rel=1e-8)
    assert speeds.inbound_far == pytest.approx(60.8, rel=1e-8)
    assert speeds.rebound_far == pytest.approx(25.4, rel=1e-8)


def test_five_stamps_give_both_speeds_four_are_refused() -> None:
    stamps = closed_form_stamps(60.8, 10.0)
    five = codec.map_stamps([*stamps[:5], None], SETUP, POSITIONS)
    assert [c.gate for c in five] == [1, 2, 3, 3, 2]
    with pytest.raises(codec.StampError, match="4 time stamps, fewer than the 5"):
        codec.map_stamps([*stamps[:4], None, None], SETUP, POSITIONS)


# Gates whose rebound pairs differ (3 -> 2 is 0.4 m, 2 -> 1 is 0.3 m): a 5-stamp shot mapped to the
# wrong pair gets a rebound speed a third off.
UNEVEN = (0.9, 0.6, 0.2)


def stamps_through(
    positions: tuple[float, float, float], v_in: float, v_out: float, contact_s: float = 0.8e-3
) -> list[float]:
    """The 6 stamps of a ball through `positions` at v_in, in contact with the bat for `contact_s`,
    back at v_out: gates 1, 2, 3, 3, 2, 1."""
    t0, x1 = 0.0123, positions[0]
    t_leave = t0 + x1 / v_in + contact_s
    return [t0 + (x1 - x) / v_in for x in positions] + [t_leave + x / v_out for x in reversed(positions)]


def rebound_of(crossings: Any, positions: tuple[float, float, float]) -> float | None:
    cfg = SETUP.gate_config()
    return shot_speeds(split_passes(crossings, cfg), positions, cfg).rebound


@pytest.mark.parametrize("v_out", [6.0, 12.0, 25.0, 40.0])
@pytest.mark.parametrize(("missed", "gates"), [(3, [1, 2, 3, 2, 1]), (5, [1, 2, 3, 3, 2])])
@pytest.mark.parametrize("positions", [UNEVEN, POSITIONS])
def test_a_five_stamp_shot_is_mapped_by_its_timing_and_gives_the_true_rebound_speed(
    v_out: float, missed: int, gates: list[int], positions: tuple[float, float, float]
) -> None:
    """Stamp 4 (the near screen on the rebound) or stamp 6 (the far screen at the end) missed: the
    interval from the inbound gate-3 stamp to the first rebound stamp tells which, and the rebound
    speed is the true one (by order alone, the first case took gates 3, 2 for 2, 1)."""
    six = stamps_through(positions, 60.8, v_out)
    five = [s for i, s in enumerate(six) if i != missed]
    crossings = codec.map_stamps([*five, None], SETUP, positions)
    assert [c.gate for c in crossings] == gates
    assert rebound_of(crossings, positions) == pytest.approx(v_out, rel=1e-6)


def test_a_five_stamp_shot_is_refused_when_its_timing_does_not_tell() -> None:
    # without the gates' positions nothing tells the two apart
    five = stamps_through(UNEVEN, 60.8, 20.0)[:5]
    with pytest.raises(codec.StampError, match="5 time stamps: which rebound screen was missed"):
        codec.map_stamps(five, SETUP)
    # gates spaced geometrically (x2^2 = x1 x3): both candidates predict the same interval
    geometric = (0.8, 0.4, 0.2)
    for missed in (3, 5):
        five = [s for i, s in enumerate(stamps_through(geometric, 60.8, 20.0)) if i != missed]
        with pytest.raises(
            codec.StampError, match=r"^ambiguous 5-stamp shot: .*: both agree within "
        ) as caught:
            codec.map_stamps(five, SETUP, geometric)
        assert "\n" not in str(caught.value)
    # a first rebound stamp that fits neither (a stray edge 40 ms late)
    five = [*stamps_through(UNEVEN, 60.8, 20.0)[:3], 0.08, 0.09]
    with pytest.raises(
        codec.StampError, match=r"^ambiguous 5-stamp shot: .*: neither agrees within 2 ms \+ 5 %$"
    ):
        codec.map_stamps(five, SETUP, UNEVEN)


@pytest.mark.parametrize(
    ("stamps", "message"),
    [
        ([0.1, 0.2, None, 0.3, 0.4, 0.5], "missing in the middle"),
        ([0.1, 0.2, 0.3, 0.25, 0.4, 0.5], "do not rise"),
        ([0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7], "more than the 6"),
        ([], "0 time stamps"),
    ],
)
def test_unmappable_stamps_are_refused(stamps: list[float | None], message: str) -> None:
    with pytest.raises(codec.StampError, match=message):
        codec.map_stamps(stamps, SETUP)


def test_fetch_reply_forms() -> None:
    assert codec.parse_stamps("+1,+1.5E-003,9.91E+37") == (1.5e-3, None)
    with pytest.raises(ValueError, match="prescaler"):
        codec.parse_stamps("+13,+1.29E-006")
    with pytest.raises(codec.ScpiErrorReply, match="-230"):
        codec.parse_stamps('-230,"Data corrupt or stale"')
    with pytest.raises(ValueError, match="not a number"):
        codec.parse_stamps("+1,+1.5E-0#3")


def test_idn_error_and_headers() -> None:
    ident = codec.parse_idn("Keysight Technologies,53230A,MY50001234,02.05-1519.666-1.19-4.15-127-155-35")
    assert (ident.maker, ident.model, ident.serial_number) == (
        "Keysight Technologies",
        "53230A",
        "MY50001234",
    )
    assert codec.parse_error('+0,"No error"') == (0, "No error")
    assert codec.parse_error('-113,"Undefined header"') == (-113, "Undefined header")
    with pytest.raises(ValueError):
        codec.parse_idn("53230A")
    for line in ("CONF:ARR:TST (6),(@1)", "configure:array:tstamp (6),(@1)", ":CONFigure:ARRay:TSTamp (6)"):
        cmd = codec.parse_command(line)
        assert cmd is not None and cmd.header == "CONFigure:ARRay:TSTamp"
        assert codec.parse_array_count(cmd.argument) == 6
    inp = codec.parse_command("INP1:LEV 1")
    assert inp is not None and (inp.header, inp.suffix, inp.argument) == ("INPut:LEVel", 1, "1")
    assert codec.parse_command("FETC") is None  # FETCh is a query only
    assert codec.parse_command("CONFX:TST") is None
    for line in codec.configure_commands(SETUP):  # every line the driver sends, the twin knows
        assert codec.parse_command(line) is not None, line


FIELD = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.sampled_from(["9.91E37", "+1", "-0", "", " ", "1e", "NaN", "INF", '"x"', "1,2", "\x00", "+9.91E+37"]),
    st.text(max_size=12),
)


@settings(max_examples=400, deadline=None)
@given(st.one_of(st.text(max_size=200), st.lists(FIELD, max_size=9).map(",".join)))
def test_hostile_fetch_replies_never_escape_as_anything_but_a_refusal(reply: str) -> None:
    try:
        stamps = codec.parse_stamps(reply)
    except ValueError:
        return
    try:
        crossings = codec.map_stamps(stamps, SETUP)
    except codec.StampError:
        return
    assert 5 <= len(crossings) <= 6
    assert all(b.tick > a.tick for a, b in itertools.pairwise(crossings))


# -- driver against the twin over TCP ----------------------------------------------------------------
@pytest.fixture
def world() -> SimWorld:
    return SimWorld(Scene.load("ideal"))


def open_gates(
    address: str,
    traffic: list[TrafficRecord],
    gate_positions_m: tuple[float, float, float] | None = None,
    **options: Any,
) -> Any:
    context = DriverContext(
        kind="gates",
        name="gates",
        address=address,
        options=options,
        on_traffic=traffic.append,
        gate_positions_m=gate_positions_m,
    )
    return open_device("gates", context, DeviceSpec(driver="scpi-counter", address=address, options=options))


@pytest.fixture
def twin_factory(world: SimWorld) -> Iterator[Any]:
    made: list[ScpiCounterTwin] = []

    def make(**faults: Any) -> ScpiCounterTwin:
        twin = ScpiCounterTwin(world, **faults)
        twin.start()
        made.append(twin)
        return twin

    yield make
    for twin in made:
        twin.close()


def fire(world: SimWorld, shot: int) -> Any:
    with world.lock:
        return world.fire(394.5, shot)


def test_driver_measures_the_worlds_shot(world: SimWorld, twin_factory: Any) -> None:
    twin = twin_factory()
    traffic: list[TrafficRecord] = []
    gates = open_gates(twin.address, traffic)
    try:
        ident = gates.identify()
        assert ident.maker == "bat-rig simulator" and ident.model == "53230A-SIM"
        gates.self_test()
        cfg = gates.config()
        assert (cfg.gates, cfg.tick_ns) == (3, 0.02)
        gates.arm()
        truth = fire(world, 1)
        crossings = list(gates.crossings(0.5))
        gates.disarm()
    finally:
        gates.close()
    assert [c.gate for c in crossings] == [1, 2, 3, 3, 2, 1]
    # each stamp difference is the true crossing-time difference to the counter's resolution
    times = [x.time_s for x in truth.crossings]
    for i in range(1, 6):
        measured = (crossings[i].tick - crossings[0].tick) * 20e-12
        assert measured == pytest.approx(times[i] - times[0], abs=25e-12)
    speeds = shot_speeds(split_passes(crossings, cfg), POSITIONS, cfg)
    true_in = (POSITIONS[1] - POSITIONS[2]) / (times[2] - times[1])
    assert speeds.inbound == pytest.approx(true_in, rel=1e-7)
    assert speeds.inbound == pytest.approx(truth.impact_speed, rel=1e-6)  # ideal scene: no drag
    assert speeds.rebound == pytest.approx(truth.rebound_speed, rel=1e-6)
    assert world.clock >= times[-1]  # the fetch waited, in virtual time, for the last edge
    sent = b"".join(r.data for r in traffic if r.direction == "tx")
    got = b"".join(r.data for r in traffic if r.direction == "rx")
    assert b"INIT\n" in sent and b"FETC?\n" in sent and b"CONF:ARR:TST (6),(@1)\n" in sent
    assert got.count(b",") >= 6 and b"bat-rig simulator" in got


def test_unknown_command_is_error_113(world: SimWorld, twin_factory: Any) -> None:
    twin = twin_factory()
    gates = open_gates(twin.address, [])
    try:
        gates.link.write("FOO:BAR 1")
        assert codec.parse_error(gates.link.query("SYST:ERR?")) == (-113, "Undefined header")
        assert codec.parse_error(gates.link.query("SYST:ERR?")) == (0, "No error")
    finally:
        gates.close()


def test_options_are_checked(world: SimWorld, twin_factory: Any) -> None:
    twin = twin_factory()
    with pytest.raises(ConfigError, match="does not know option 'channel'"):
        open_gates(twin.address, [], channel=2)
    with pytest.raises(ConfigError, match="min_edges"):
        open_gates(twin.address, [], min_edges=2)


def test_nothing_listening_is_device_gone() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound, never listening: connection refused
        with pytest.raises(DeviceGone, match=f"127.0.0.1::{port}"):
            open_gates(f"TCPIP0::127.0.0.1::{port}::SOCKET", [])


def test_too_few_stamps_refuse_the_shot(world: SimWorld, twin_factory: Any) -> None:
    twin = twin_factory(short_on_shot=1, short_by=3)
    traffic: list[TrafficRecord] = []
    gates = open_gates(twin.address, traffic)
    try:
        gates.arm()
        fire(world, 1)
        with pytest.raises(UnexpectedMessage, match="3 time stamps, fewer than the 5"):
            list(gates.crossings(0.5))
        assert list(gates.crossings(0.5)) == []  # refused once, not fetched again and mended
        gates.arm()  # the next shot is measured
        fire(world, 2)
        assert len(list(gates.crossings(0.5))) == 6
    finally:
        gates.close()
    assert b"9.91" in b"".join(r.data for r in traffic if r.direction == "rx")  # the raw reply kept


def uneven_world(positions: tuple[float, float, float]) -> SimWorld:
    ideal = Scene.load("ideal")
    rig = ideal.rig.model_copy(update={"gate_positions_m": positions})
    return SimWorld(ideal.model_copy(update={"rig": rig}))


def shot_missing_a_rebound_screen(
    positions: tuple[float, float, float], blind: int
) -> tuple[list[GateCrossing] | UnexpectedMessage, Any]:
    """One shot through the twin on gates at `positions` whose rebound misses screen `blind`: the
    driver's crossings (or its refusal) and the world's truth of the shot."""
    world = uneven_world(positions)
    twin = ScpiCounterTwin(world, miss_rebound_on_shot=1, miss_rebound_gate=blind)
    twin.start()
    gates = open_gates(twin.address, [], gate_positions_m=positions)
    try:
        gates.arm()
        truth = fire(world, 1)
        try:
            return list(gates.crossings(0.5)), truth
        except UnexpectedMessage as exc:
            return exc, truth
    finally:
        gates.close()
        twin.close()


@pytest.mark.parametrize(("blind", "order"), [(3, [1, 2, 3, 2, 1]), (1, [1, 2, 3, 3, 2])])
def test_a_rebound_that_misses_a_screen_gives_the_true_rebound_speed_or_is_refused(
    blind: int, order: list[int]
) -> None:
    """Through the twin, a rebound that misses the near screen (gate 3) or the far one (gate 1):
    with the gates' positions (as the session gives them) the driver maps the 5 stamps by their
    timing and the rebound speed is the world's; on gates spaced so that the timing cannot tell,
    the shot is refused in one line; never a wrong speed."""
    crossings, truth = shot_missing_a_rebound_screen(UNEVEN, blind)
    assert not isinstance(crossings, UnexpectedMessage)
    assert [c.gate for c in crossings] == order
    assert rebound_of(crossings, UNEVEN) == pytest.approx(truth.rebound_speed, rel=1e-6)  # ideal: no drag

    refused, _ = shot_missing_a_rebound_screen((0.8, 0.4, 0.2), blind)  # geometric: the timing cannot tell
    assert isinstance(refused, UnexpectedMessage)
    assert "shot refused: ambiguous 5-stamp shot: " in str(refused)


def test_a_write_to_a_closed_peer_leaves_no_tx_record_of_the_failed_line(
    world: SimWorld, twin_factory: Any
) -> None:
    """The counter hangs up: the first write after it may still reach the socket, a later one fails
    (broken pipe). Each line written is in the record; the line whose write failed never left and is
    not."""
    twin = twin_factory()
    traffic: list[TrafficRecord] = []
    gates = open_gates(twin.address, traffic)
    try:
        twin._hang_up()
        time.sleep(0.05)
        found = write_until_one_fails(lambda i: gates.link.write(f"INP1:LEV {i}"))
    finally:
        gates.close()
    assert found is not None, "no write to the closed peer failed"
    failed = found[0]
    sent = [r.data for r in traffic if r.direction == "tx"]
    assert f"INP1:LEV {failed}\n".encode() not in sent
    assert all(f"INP1:LEV {i}\n".encode() in sent for i in range(failed))


def test_garbled_reply_is_fetched_again(world: SimWorld, twin_factory: Any) -> None:
    twin = twin_factory(garble_on_shot=1)
    gates = open_gates(twin.address, [])
    try:
        gates.arm()
        fire(world, 1)
        with pytest.raises(GarbledReply, match="FETC"):
            list(gates.crossings(0.5))
        assert [c.gate for c in gates.crossings(0.5)] == [1, 2, 3, 3, 2, 1]  # counter memory read again
    finally:
        gates.close()


def test_silent_fetch_times_out_then_recovers(world: SimWorld, twin_factory: Any) -> None:
    twin = twin_factory(silent_on_shot=1)
    gates = open_gates(twin.address, [], fetch_timeout_s=0.5)
    try:
        gates.arm()
        fire(world, 1)
        with pytest.raises(DeviceTimeout, match="no reply to FETC\\? from TCPIP0::"):
            list(gates.crossings(0.5))
        gates.arm()  # reopens the connection first: no late reply is taken for a later answer
        fire(world, 2)
        assert len(list(gates.crossings(0.5))) == 6
    finally:
        gates.close()


def test_dropped_connection_is_device_gone(world: SimWorld, twin_factory: Any) -> None:
    twin = twin_factory(drop_on_shot=1)
    gates = open_gates(twin.address, [], fetch_timeout_s=1.0)
    try:
        gates.arm()
        fire(world, 1)
        with pytest.raises(DeviceGone, match="closed the connection"):
            list(gates.crossings(0.5))
        gates.reconnect()  # a replug: the instrument is there again
        assert gates.identify().maker == "bat-rig simulator"
    finally:
        gates.close()


# -- a certification with the gates on the twin, cannon and clamp on sim:// of the same world ----------
def twin_rig(name: str, **faults: Any) -> tuple[RigConfig, SimWorld, ScpiCounterTwin, BatSpec]:
    bat = BatSpec.load(SAMPLE_BAT)
    cfg = sim_config("lab", rig_name=name, bat=bat, session="scpi")  # installs the world now
    world = get_world(name)
    twin = ScpiCounterTwin(world, **faults)
    twin.start()
    data = cfg.model_dump(mode="json")
    data["devices"] = {"gates": twin.device_table()}
    return RigConfig.from_dict(data), world, twin, bat


@pytest.fixture
def clean_worlds() -> Iterator[None]:
    reset_worlds()
    yield
    reset_worlds()


def run(name: str, **faults: Any) -> tuple[Any, list[Any], SimWorld]:
    config, world, twin, bat = twin_rig(name, **faults)
    try:
        with Store.open(os.path.join(tempfile.mkdtemp(), "r.db")) as store:
            out = certify(store, Procedure.load("bbcor"), bat, config)
            entries = store.entries(out.run_id)
    finally:
        twin.close()
    return out, entries, world


@pytest.mark.usefixtures("clean_worlds")
def test_certification_through_the_twin_agrees_with_truth() -> None:
    out, entries, world = run("scpi-cert")
    assert out.status == "finished" and out.verdict.verdict in ("PASS", "FAIL")
    fired = [e.payload for e in entries if e.kind == "ShotFired"]
    assert len(fired) == len(world.shots)  # every ball the world launched is a recorded shot, once
    assert all(n == 1 for n in Counter(p["index"] for p in fired).values())
    measured = {e.payload["index"]: e.payload for e in entries if e.kind == "ShotMeasured"}
    assert len(measured) >= 6
    checked = 0
    for p in fired:
        if p["index"] not in measured:
            continue
        truth = world.shots[p["shot_number"] - 1]
        m = measured[p["index"]]
        assert [c["gate"] for c in p["crossings"]] == [1, 2, 3, 3, 2, 1]
        # speeds at the impact point against the world's truth, within their expanded uncertainty (k=2)
        outputs = m["budget"]["outputs"]
        assert abs(m["inbound_at_impact_m_s"] - truth.impact_speed) <= outputs["v_in"]["U"]
        assert abs(m["rebound_at_impact_m_s"] - truth.rebound_speed) <= outputs["v_out"]["U"]
        checked += 1
    assert checked == len(measured)
    traffic = [
        c for e in entries if e.kind == "Traffic" for c in e.payload["chunks"] if c["device"] == "gates"
    ]
    sent = b"".join(base64.b64decode(c["data_b64"]) for c in traffic if c["dir"] == "tx")
    got = b"".join(base64.b64decode(c["data_b64"]) for c in traffic if c["dir"] == "rx")
    assert sent.count(b"FETC?\n") >= len(fired) and sent.count(b"INIT\n") >= len(fired)
    assert got.count(b"+1,+") >= len(fired)  # the fetched stamp arrays, prescaler first


@pytest.mark.usefixtures("clean_worlds")
@pytest.mark.parametrize(
    ("faults", "cause"),
    [
        ({"short_on_shot": 3, "short_by": 2}, "UnexpectedMessage: gates: shot refused: 4 time stamps"),
        ({"silent_on_shot": 3}, "DeviceTimeout: gates: no reply to FETC?"),
    ],
)
def test_a_counter_fault_loses_one_shot_and_the_run_goes_on(faults: dict[str, int], cause: str) -> None:
    out, entries, world = run(f"scpi-fault-{next(iter(faults))}", **faults)
    assert out.status == "finished" and out.verdict.verdict in ("PASS", "FAIL")
    lost = [e.payload for e in entries if e.kind == "ShotLost"]
    assert [p["reason"].startswith(cause) for p in lost] == [True], lost
    assert "\n" not in lost[0]["reason"]
    requested = Counter(e.payload["index"] for e in entries if e.kind == "ShotRequested")
    fired = Counter(e.payload["index"] for e in entries if e.kind == "ShotFired")
    assert all(n == 1 for n in requested.values()) and all(n == 1 for n in fired.values())
    # the lost shot's ball was launched once; every other launch is a recorded shot
    assert len(world.shots) == sum(fired.values()) + 1
    lost_traffic = [e for e in entries if e.kind == "Traffic" and e.payload["index"] == lost[0]["index"]]
    assert lost_traffic and any(c["device"] == "gates" for c in lost_traffic[0].payload["chunks"])


@pytest.mark.usefixtures("clean_worlds")
def test_a_dropped_counter_connection_loses_that_shot_and_the_next_arm_reconnects() -> None:
    out, entries, world = run("scpi-drop", drop_on_shot=3)
    assert out.status == "finished" and out.verdict.verdict in ("PASS", "FAIL")
    fired = [e.payload for e in entries if e.kind == "ShotFired"]
    assert len(world.shots) == len(fired)  # nothing fired twice, nothing fired unrecorded
    (dropped,) = [p for p in fired if p["shot_number"] == 3]
    assert dropped["crossings"] == []  # recorded, raw and empty: nothing was made up
    (rejected,) = [
        e.payload for e in entries if e.kind == "ShotRejected" and e.payload["index"] == dropped["index"]
    ]
    (failed,) = [r for r in rejected["reasons"] if r["code"] == "SHOT_FAILED"]
    assert failed["message"].startswith("device lost mid-shot")
    assert "FETC?: TCPIP0::127.0.0.1::" in failed["message"] and "closed the connection" in failed["message"]


def test_scpi_counter_is_refused_as_another_kind() -> None:
    from rig.drivers.registry import factory_for

    with pytest.raises(ConfigError, match="driver 'scpi-counter' drives the gates, not the cannon"):
        factory_for("cannon", DeviceSpec(driver="scpi-counter", address="TCPIP0::127.0.0.1::1::SOCKET"))

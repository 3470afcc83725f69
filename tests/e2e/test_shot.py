"""One shot end to end: real drivers on simulated devices, in-process and across a process boundary."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from rig.certification import certify
from rig.cli import main
from rig.core.bat import BatSpec
from rig.core.devices import CannonState
from rig.core.errors import DeviceError, DeviceGone, DeviceTimeout, RigError, SafetyRefusal
from rig.physics import DEFAULT_PARAMS, PivotedBat, predict_bat
from rig.protocols.procedure import Procedure
from rig.protocols.shot import ShotFailed, fire_shot, prepare
from rig.session import RigSession, sim_config
from rig.simulators.scene import Scene
from rig.simulators.urlhandler import get_world, register, reset_worlds
from rig.store import Store
from tests.load import stop_group

RIG = [sys.executable, "-m", "rig.cli"]
SERVE = [*RIG, "sim", "serve"]


@pytest.fixture(autouse=True)
def _shots_recorded_here(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`rig shot` records each shot as a run: here in a store of the test's own (RIG_DB, which the
    `rig` processes the tests start inherit), never in the working directory."""
    monkeypatch.setenv("RIG_DB", str(tmp_path / "shots.db"))


def test_cli_shot_in_ideal_scene_matches_the_model(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["shot", "--sim", "ideal", "--speed", "60.8", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [c["gate"] for c in out["crossings"]] == [1, 2, 3, 3, 2, 1]
    assert out["gate_positions_m"] == [0.75, 0.5, 0.25]
    assert all(isinstance(c["tick"], int) and c["host_time_s"] > 0 for c in out["crossings"])
    # aiming from the calibration table lands within 1 % of the target
    assert out["inbound_speed_m_s"] == pytest.approx(60.8, rel=0.01)
    # ideal scene: rigid barrel on the pivoted bat; the rebound is the model's e_A x v_in
    bat = Scene.load("ideal").bat
    q = out["impact_from_pivot_m"]
    expected = predict_bat(
        DEFAULT_PARAMS,
        out["inbound_speed_m_s"],
        None,
        PivotedBat(moi_kgm2=bat.moi_kgm2, impact_from_pivot_m=q),
    )
    e_a = out["rebound_speed_m_s"] / out["inbound_speed_m_s"]
    assert e_a == pytest.approx(expected.e_a, abs=2e-4)  # tick quantization over ~23 ms


def test_cli_shot_failure_is_one_line_and_nonzero(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["shot", "--sim", "ideal", "--speed", "150"]) == 2  # beyond the aim calibration
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err and "aim calibration" in err


def test_cli_shot_needs_a_rig(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["shot", "--speed", "60.8", "--cannon", "sim://cannon"]) == 2
    assert "--gates" in capsys.readouterr().err


def test_unplugged_device_path_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    argv = [
        "shot",
        "--speed",
        "60.8",
        "--cannon",
        "/dev/does-not-exist-rig",
        "--gates",
        "loop://",
        "--clamp",
        "loop://",
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "cannon" in err and "does-not-exist-rig" in err


def test_no_fire_with_an_open_interlock() -> None:
    cfg = sim_config("ideal")
    with RigSession.open(cfg) as s:
        gc = prepare(s.cannon, s.gates, s.clamp, cfg.impact_from_pivot_m)
        world = get_world(cfg.ports.cannon.split("rig=")[1])
        for name in ("door", "estop"):
            world.set_interlock(name, closed=False)
            shots_before = s.cannon.status().shots
            with pytest.raises(SafetyRefusal, match=name):
                fire_shot(s.cannon, s.gates, s.clamp, cfg, 60.8, gc)
            assert s.cannon.status().shots == shots_before
            assert s.cannon.status().state is not CannonState.ARMED
            world.set_interlock(name, closed=True)
        assert b"FIRE" not in b"".join(
            rec.data for dev, rec in s.traffic if dev == "cannon" and rec.direction == "tx"
        )
        fire_shot(s.cannon, s.gates, s.clamp, cfg, 60.8, gc)  # all closed again: it fires


def test_every_fault_of_the_faulty_scene_ends_clearly() -> None:
    """Each shot either measures (recovered) or raises a typed error; no hang, nothing lost."""
    cfg = sim_config("faulty")
    outcomes: list[str] = []
    with RigSession.open(cfg) as s:
        gc = prepare(s.cannon, s.gates, s.clamp, cfg.impact_from_pivot_m)
        for _ in range(9):
            t0 = time.monotonic()
            try:
                rec = fire_shot(s.cannon, s.gates, s.clamp, cfg, 60.8, gc)
                outcomes.append("ok" if not rec.extra_crossings else "ok-extra")
                assert rec.inbound_speed_m_s == pytest.approx(60.8, rel=0.01)
            except ShotFailed as exc:
                outcomes.append("failed")
                assert exc.record is not None and exc.record.crossings  # raw events kept
            except RigError as exc:
                outcomes.append(type(exc).__name__)
                assert str(exc)
            assert time.monotonic() - t0 < 5.0
            _recover(s)
    assert outcomes[0] == "ok"
    assert outcomes[1] == "DeviceError"  # misfire: FAULT, then RESET
    assert outcomes[2] == "ok"  # missed middle trigger: the outer pair still gives the speed
    assert outcomes[3] == "ok-extra"  # doubled trigger set aside
    assert outcomes[6] == "failed"  # gates unplugged mid-shot, partial record kept
    assert outcomes[7] == "SafetyRefusal"  # door opened after ARM: FIRE never sent
    assert outcomes[8] == "ok"  # and the rig is back to normal
    gates_rx = b"".join(rec.data for dev, rec in s.traffic if dev == "gates" and rec.direction == "rx")
    # every gate event byte is in the traffic log, the garbled one and those of failed shots too
    assert gates_rx.count(b"! G ") == 6 + 5 + 7 + 6 + 6 + 2 + 6


def _recover(s: RigSession) -> None:
    for dev in (s.cannon, s.gates, s.clamp):
        try:
            dev.identify()
        except DeviceGone:
            dev.reconnect()
        except DeviceTimeout:
            pass
    try:
        if s.cannon.status().state is CannonState.FAULT:
            s.cannon.reset()
    except DeviceTimeout:
        pass  # the faulty scene drops one STATUS reply on purpose
    except DeviceError:
        raise


@contextlib.contextmanager
def served(*args: str) -> Iterator[dict[str, str]]:
    """`rig sim serve ARGS` in its own process group; yields its device URLs; always stopped."""
    server = subprocess.Popen(
        [*SERVE, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    assert server.stdout is not None and server.stderr is not None
    try:
        urls = {}
        # the warm-up (in a fresh checkout: compiling the kernel) comes before the first line
        deadline = time.monotonic() + 120
        while len(urls) < 3 and time.monotonic() < deadline:
            line = server.stdout.readline()
            if not line:
                break
            name, url = line.split()
            urls[name] = url
        assert set(urls) == {"cannon", "gates", "clamp"}, server.stderr.read() if server.poll() else urls
        yield urls
    finally:
        stop_group(server)
        server.stdout.close()
        server.stderr.close()


def _urls(urls: dict[str, str]) -> list[str]:
    return [a for d in ("cannon", "gates", "clamp") for a in (f"--{d}", urls[d])]


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX process groups")
@pytest.mark.parametrize("kind", ["tcp", "pty"])
@pytest.mark.usefixtures("cpu_load")
def test_shot_through_rig_sim_serve(kind: str) -> None:
    """The real drivers cross a real OS boundary to a `rig sim serve` process."""
    with served("--scene", "lab", "--kind", kind) as urls:
        proc = subprocess.run(
            [*RIG, "shot", "--speed", "60.8", "--json", *_urls(urls)],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert len(out["crossings"]) >= 6
    assert out["inbound_speed_m_s"] == pytest.approx(60.8, rel=0.02)
    assert 5.0 < out["rebound_speed_m_s"] < 30.0
    assert out["recoil_rad_s"] > 0  # the lab scene turns on bat recoil


def _ports(scene: str, rig: str) -> list[str]:
    return [a for d in ("cannon", "gates", "clamp") for a in (f"--{d}", f"sim://{d}?scene={scene}&rig={rig}")]


def test_cli_shot_resets_a_cannon_an_earlier_shot_left_in_fault(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A misfire leaves the cannon in FAULT; the next `rig shot` clears it (RESET) and fires."""
    scene = tmp_path / "misfire.toml"
    scene.write_text('[[effects]]\nkind = "misfire"\nshots = [2]\n')
    ports = _ports(str(scene), "shot-fault")
    register()
    reset_worlds()
    try:
        assert main(["shot", "--speed", "60.8", "--json", *ports]) == 0
        capsys.readouterr()
        assert main(["shot", "--speed", "60.8", *ports]) == 2  # the misfire
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "MISFIRE" in err and "next `rig shot` resets it" in err
        world = get_world("shot-fault")
        assert world.cannon.state is CannonState.FAULT  # and so it stays, across sessions
        assert main(["shot", "--speed", "60.8", "--json", *ports]) == 0
        captured = capsys.readouterr()
        assert "FAULT" in captured.err and "reset" in captured.err
        out = json.loads(captured.out)
        assert out["shot_number"] == 2  # the cannon's count of balls launched: the misfire launched none
        assert out["inbound_speed_m_s"] == pytest.approx(60.8, rel=0.01)
        assert world.attempts == 3 and len(world.shots) == 2  # three FIREs accepted, two balls flew
        assert world.cannon.state is not CannonState.FAULT
    finally:
        reset_worlds()


HEAVY_BAT = """[bat]
id = "HEAVY-MOI"
length_in = 33.0
weight_oz = 30.0
barrel = "aluminium"
moi_kgm2 = 0.30
"""


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX process groups")
@pytest.mark.usefixtures("cpu_load")
def test_rig_sim_serve_simulates_the_bat_file(tmp_path: Path) -> None:
    """`rig sim serve --bat`: the served bat has the file's MOI, so the rebound is that bat's."""
    bat = tmp_path / "heavy.toml"
    bat.write_text(HEAVY_BAT)
    with served("--scene", "ideal", "--kind", "tcp", "--bat", str(bat)) as urls:
        argv = [*RIG, "shot", "--speed", "60.8", "--json", *_urls(urls)]
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    e_a = out["rebound_speed_m_s"] / out["inbound_speed_m_s"]

    def model(moi: float) -> float:
        bat = PivotedBat(moi_kgm2=moi, impact_from_pivot_m=out["impact_from_pivot_m"])
        return predict_bat(DEFAULT_PARAMS, out["inbound_speed_m_s"], None, bat).e_a

    assert Scene.load("ideal").bat.moi_kgm2 == 0.19  # what the scene alone would simulate
    assert e_a == pytest.approx(model(0.30), abs=2e-4)  # tick quantization over ~23 ms
    assert abs(e_a - model(0.19)) > 0.05


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ('[bat]\nid = "X"\nlength_in = 33.0\nweight_oz = 30.0\nbarrel = "wood"\nmoi_kgm2 = 0.05\n', "MOI"),
        ('[bat]\nid = "X"\nlength_in = 33.0\nbarrel = "wood"\n', "weight_oz"),
    ],
)
def test_rig_sim_serve_refuses_a_bad_bat_file_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, needle: str
) -> None:
    bat = tmp_path / "bad.toml"
    bat.write_text(text)
    assert main(["sim", "serve", "--scene", "ideal", "--kind", "tcp", "--bat", str(bat)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err and "bad.toml" in err and needle in err


@pytest.mark.parametrize("port", ["70000", "65534", "-1", "x"])
def test_rig_sim_serve_refuses_a_base_port_out_of_range(
    capsys: pytest.CaptureFixture[str], port: str
) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["sim", "serve", "--kind", "tcp", "--base-port", port])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "--base-port" in err


SAMPLE_BAT = Path(__file__).resolve().parents[2] / "protocols" / "examples" / "sample-bat.toml"
OUTCOMES = ("ShotMeasured", "ShotRejected", "ShotLost")


def _outcomes(db: Path) -> tuple[list[tuple[str, int, float | None]], dict]:
    """(kind, shot index, metric) of every shot's outcome, and the RunFinished payload."""
    with Store.open(db, create=False) as store:
        (run,) = store.runs()
        shots = [
            (e.kind, e.payload["index"], e.payload.get("metric"))
            for e in store.entries(run.run_id, kinds=OUTCOMES)
        ]
        (finished,) = store.entries(run.run_id, kinds=["RunFinished"])
        assert store.verify().ok
    return shots, finished.payload


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX process groups")
@pytest.mark.usefixtures("cpu_load")
def test_certify_on_a_served_rig_loses_no_shot_and_matches_the_in_process_run(tmp_path: Path) -> None:
    """`rig certify --config` on `rig sim serve --bat` under load: every shot is the in-process run's.

    Virtual time makes the simulated rig deterministic, so the record of a run across the process
    boundary (TCP) must equal the record of the same run in process (sim://): no shot lost to a slow
    first reply, the same outcomes and metrics, the same verdict.
    """
    with served("--scene", "lab", "--kind", "tcp", "--bat", str(SAMPLE_BAT)) as urls:
        fragment = Scene.load("lab").rig_config_fragment()
        rig_toml = tmp_path / "rig.toml"
        rig_toml.write_text(
            "[ports]\n"
            + "".join(f'{d} = "{urls[d]}"\n' for d in ("cannon", "gates", "clamp"))
            + f"[gates]\npositions_m = {list(fragment['gates']['positions_m'])}\n"
            + f"[aim]\npressure_kpa = {list(fragment['aim']['pressure_kpa'])}\n"
            + f"speed_m_s = {list(fragment['aim']['speed_m_s'])}\n"
            + "[air]\n"  # the lab states the drag coefficients it measured (the scene's own)
            + "".join(f"{k} = {v}\n" for k, v in fragment["air"].items())
        )
        served_db = tmp_path / "served.db"
        files = ["--bat", str(SAMPLE_BAT), "--config", str(rig_toml), "--db", str(served_db)]
        proc = subprocess.run(
            [*RIG, "certify", "--procedure", "bbcor", *files],
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr  # PASS or FAIL: a verdict
    bat = BatSpec.load(SAMPLE_BAT)
    ref_db = tmp_path / "in-process.db"
    with Store.open(ref_db) as store:
        certify(store, Procedure.load("bbcor"), bat, sim_config("lab", bat=bat))
    shots, verdict = _outcomes(served_db)
    reference, ref_verdict = _outcomes(ref_db)
    assert not [s for s in shots if s[0] == "ShotLost"]
    assert [s[:2] for s in shots] == [s[:2] for s in reference]
    assert [s[2] for s in shots] == pytest.approx([s[2] for s in reference], abs=1e-12)
    assert verdict["verdict"] == ref_verdict["verdict"]
    assert verdict["mean"] == pytest.approx(ref_verdict["mean"], abs=1e-12)

"""Finding 4: the MOI's u is derived from the pendulum's inputs (ASTM F2398), not a fixed 0.5 %."""

from __future__ import annotations

import base64
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rig.certification import certify
from rig.cli import main
from rig.core.bat import BatSpec
from rig.core.config import Pendulum
from rig.core.errors import ConfigError
from rig.measure.moi import PendulumReading, PendulumUncertainty, entered_budget, pendulum_budget
from rig.protocols.procedure import Procedure
from rig.report.record import run_record
from rig.session import sim_config
from rig.simulators.physics import pendulum_period
from rig.store import Store

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
UNC = PendulumUncertainty(
    timer_resolution_s=1e-4,
    scale_resolution_kg=0.002,
    lever_half_width_m=0.001,
    amplitude_deg=1.0,
    gravity_m_s2=0.01,
)


def _reading(periods: tuple[float, ...], amp_deg: float = 8.0) -> PendulumReading:
    return PendulumReading(periods, 10, amp_deg, 0.85, 0.41, 9.80665)


def test_the_pendulum_formula_inverts_the_simulators_period() -> None:
    # the simulator's own period function (finite amplitude) for a known MOI, read back
    for moi, amp in ((0.19, 5.0), (0.25, 12.0), (0.12, 1.0)):
        t = pendulum_period(moi, 0.85, 0.41, math.radians(amp))
        assert pendulum_budget(_reading((t,), amp), UNC).moi_kgm2 == pytest.approx(moi, rel=1e-12)


def _monte_carlo(
    reading: PendulumReading, unc: PendulumUncertainty, only: str | None, n: int = 400_000
) -> float:
    """u(I) by drawing the inputs and evaluating I = m g d T0^2/(4 pi^2), written out here."""
    rng = np.random.default_rng(1)
    r = len(reading.periods_s)

    def on(name: str) -> float:
        return 1.0 if only in (None, name) else 0.0

    t_bar = float(np.mean(reading.periods_s))
    s = float(np.std(reading.periods_s, ddof=1)) if r > 1 else 0.0
    # a timing is an interval between two quantized instants: the difference of two uniform errors
    q = rng.uniform(-0.5, 0.5, (n, r, 2)) * unc.timer_resolution_s
    t = t_bar + on("T_res") * ((q[..., 1] - q[..., 0]) / reading.cycles).mean(axis=1)
    t = t + on("T_scatter") * rng.normal(0.0, s / math.sqrt(r), n)
    m = reading.mass_kg + on("m_bat") * rng.uniform(-0.5, 0.5, n) * unc.scale_resolution_kg
    d = reading.lever_m + on("d") * rng.uniform(-1.0, 1.0, n) * unc.lever_half_width_m
    amp = np.radians(reading.amplitude_deg + on("theta0") * rng.normal(0.0, unc.amplitude_deg, n))
    g = reading.gravity_m_s2 + on("g") * rng.normal(0.0, unc.gravity_m_s2, n)
    t0 = t / (1.0 + amp**2 / 16.0)
    return float(np.std(m * g * d * t0**2 / (4.0 * np.pi**2)))


def test_derived_u_agrees_with_a_monte_carlo_of_the_pendulum_formula() -> None:
    reading = _reading((1.4883, 1.4886, 1.4879, 1.4884))
    found = pendulum_budget(reading, UNC)
    assert found.u_kgm2 == pytest.approx(_monte_carlo(reading, UNC, None), rel=0.02)
    rows = {i.name: i for i in found.inputs}
    assert len([i for i in found.inputs if i.u_moi > 0]) >= 5
    for name, row in rows.items():  # each input's own contribution, one at a time
        assert row.u_moi == pytest.approx(_monte_carlo(reading, UNC, name), rel=0.03, abs=1e-9), name
    assert sum(i.share for i in found.inputs) == pytest.approx(1.0)


def test_scatter_of_repeated_timings_raises_u() -> None:
    steady = pendulum_budget(_reading((1.4883, 1.4883, 1.4883)), UNC)
    wobbly = pendulum_budget(_reading((1.4853, 1.4883, 1.4913)), UNC)
    assert wobbly.u_kgm2 > steady.u_kgm2
    scatter = next(i for i in wobbly.inputs if i.name == "T_scatter")
    assert scatter.u == pytest.approx(0.003 / math.sqrt(3), rel=1e-9)  # s / sqrt(n) of the three


def test_an_entered_moi_carries_its_own_u() -> None:
    found = entered_budget(0.2, 0.003)
    assert (found.moi_kgm2, found.u_kgm2, found.source) == (0.2, 0.003, "entered")
    with pytest.raises(ValueError):
        entered_budget(0.2, 0.0)


# -- through the rig: the wire, the record, the budget of the metric ------------------------------


def _clamp_rx_lines(store: Store, run_id: str) -> list[str]:
    data = b"".join(
        base64.b64decode(c["data_b64"])
        for e in store.entries(run_id, kinds=["Traffic"])
        for c in e.payload["chunks"]
        if c["device"] == "clamp" and c["dir"] == "rx"
    )
    return data.decode().splitlines()


@pytest.fixture(scope="module")
def lab_run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    bat = BatSpec.load(SAMPLE_BAT)
    config = sim_config("lab", bat=bat)
    with Store.open(tmp_path_factory.mktemp("moi") / "r.db") as store:
        out = certify(store, Procedure.load("bbcor"), bat, config)
        return {
            "record": run_record(store, out.run_id),
            "wire": _clamp_rx_lines(store, out.run_id),
            "config": config,
        }


def test_the_recorded_moi_is_the_one_timed_on_the_wire(lab_run: dict[str, Any]) -> None:
    moi, config = lab_run["record"]["moi"], lab_run["config"]
    events = [re.search(r"PERIOD US=([\d.]+) AMP=([\d.]+) N=(\d+)", line) for line in lab_run["wire"]]
    timed = [(float(m[1]) * 1e-6, float(m[2]), int(m[3])) for m in events if m]
    assert len(timed) == Procedure.load("bbcor").moi.repeats == 3
    assert moi["periods_s"] == pytest.approx([t for t, _, _ in timed], rel=1e-12)
    bat = BatSpec.load(SAMPLE_BAT)
    t0 = np.mean([t for t, _, _ in timed]) / (1.0 + math.radians(timed[0][1]) ** 2 / 16.0)
    lever = (bat.balance_point_in - 6.0) * 0.0254
    expected = bat.mass_kg * config.pendulum.gravity_m_s2 * lever * t0**2 / (4.0 * math.pi**2)
    assert moi["moi_kgm2"] == pytest.approx(expected, rel=1e-9)


def test_record_moi_section_has_contributions_and_feeds_the_metric_budget(lab_run: dict[str, Any]) -> None:
    rec = lab_run["record"]
    moi = rec["moi"]
    rows = {c["input"]: c for c in moi["contributions"]}
    assert {"T_res", "T_scatter", "m_bat", "d", "theta0", "g"} <= set(rows)
    assert math.sqrt(sum(c["u_moi_kgm2"] ** 2 for c in rows.values())) == pytest.approx(moi["u_kgm2"])
    assert moi["u_kgm2"] / moi["moi_kgm2"] != pytest.approx(0.005)  # no longer the fixed 0.5 %
    budget = rec["verdict"]["budget"]
    assert budget["inputs"]["I"]["u"] == pytest.approx(moi["u_kgm2"], rel=1e-12)
    assert budget["inputs"]["I"]["systematic"]  # shared by every hit of the bat: correlated


def test_pendulum_inputs_change_the_moi_u_and_the_verdicts_u(tmp_path: Path) -> None:
    bat = BatSpec.load(SAMPLE_BAT)
    got = {}
    for name, pend in (("base", Pendulum()), ("coarse g", Pendulum(gravity_u_m_s2=0.05))):
        config = sim_config("ideal", bat=bat).model_copy(update={"pendulum": pend})
        with Store.open(tmp_path / f"{name}.db") as store:
            out = certify(store, Procedure.load("bbcor"), bat, config)
            got[name] = run_record(store, out.run_id)
    assert got["coarse g"]["moi"]["u_kgm2"] > 2 * got["base"]["moi"]["u_kgm2"]
    assert got["coarse g"]["verdict"]["U"] > got["base"]["verdict"]["U"]


def test_an_entered_moi_without_its_u_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    proc = tmp_path / "entered.toml"
    text = (
        (ROOT / "protocols" / "bbcor.toml").read_text().replace('source = "pendulum"', 'source = "entered"')
    )
    proc.write_text(text)
    bat = tmp_path / "bat.toml"
    bat.write_text(SAMPLE_BAT.read_text().replace("# moi_kgm2 = 0.19", "moi_kgm2 = 0.19"))
    args = [
        "certify",
        "--procedure",
        str(proc),
        "--bat",
        str(bat),
        "--sim",
        "ideal",
        "--db",
        str(tmp_path / "r.db"),
    ]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "moi_u_kgm2" in err and "Traceback" not in err
    with pytest.raises(ConfigError, match="moi_u_kgm2"), Store.open(tmp_path / "r2.db") as store:
        certify(store, Procedure.load(proc), BatSpec.load(bat), sim_config("ideal"))
    bat.write_text(bat.read_text().replace("moi_kgm2 = 0.19", "moi_kgm2 = 0.19\nmoi_u_kgm2 = 0.0012"))
    with Store.open(tmp_path / "r3.db") as store:
        out = certify(store, Procedure.load(proc), BatSpec.load(bat), sim_config("ideal"))
        rec = run_record(store, out.run_id)
    assert rec["moi"]["source"] == "entered" and rec["moi"]["u_kgm2"] == 0.0012
    assert rec["verdict"]["budget"]["inputs"]["I"]["u"] == pytest.approx(0.0012)


def test_old_procedures_with_a_fixed_relative_uncertainty_still_load() -> None:
    data = Procedure.load("bbcor").model_dump(mode="json")
    del data["moi"]["repeats"]
    data["moi"]["relative_uncertainty"] = 0.005  # as RunStarted payloads recorded it before
    p = Procedure.model_validate(data)
    assert p.moi.repeats == 3 and "relative_uncertainty" not in p.model_dump(mode="json")["moi"]


def test_certificate_lists_the_moi_inputs_and_the_drag_correction(
    lab_run: dict[str, Any], tmp_path: Path
) -> None:
    from rig.report.certificate import render

    rec = lab_run["record"]
    md = render(rec, "md", figures_dir=tmp_path / "f", output=tmp_path / "c.md")
    moi_section = md.split("### MOI and its uncertainty")[1].split("\n## ")[0]
    for c in rec["moi"]["contributions"]:
        assert re.search(rf"^\| {c['input']} \| {re.escape(c['what'])} \|", moi_section, flags=re.M)
    g = next(c for c in rec["moi"]["contributions"] if c["input"] == "g")
    assert f"| {100 * g['share']:.1f} % |" in moi_section
    drag = md.split("### Drag correction")[1].split("###")[0]
    air = rec["verdict"]["drag"]["air"]
    assert f"| air density (kg/m³) | {air['rho_kgm3']:.4f} |" in drag
    assert f"{rec['verdict']['drag']['correction']:.5f}" in drag
    budget_rows = re.findall(r"^\| (\w+) \| .* \| (?:systematic|random) \|", md, flags=re.M)
    assert {"I", "Cd_in", "Cd_out", "rho"} <= set(budget_rows) <= set(rec["verdict"]["budget"]["inputs"])

"""The metric registry (rig.measure.registry): each metric declared once, and a new one is an entry
and a procedure file.

The toy metric below takes exactly two things and nothing else of the repository: its registry
entry (here `TOY`, through the public `registered`; for a lab, one entry in rig/measure/registry.py
or a `register` call) and one procedure file (`toy.toml`, written to the test's directory). With
them a bat is certified on the simulated rig, and the record, the certificate and `rig runs --json`
carry the metric.
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path
from typing import Any

import pytest

import rig
from rig.cli import main
from rig.core.errors import ConfigError
from rig.measure import registry
from rig.measure.metrics import compute_metrics
from rig.measure.model import OUTPUTS, ShotInputs, outputs
from rig.measure.registry import Metric, MetricTerms
from rig.population.dataset import METRICS
from rig.protocols.procedure import Procedure
from rig.report.record import run_record

ROOT = Path(__file__).resolve().parents[2]
SAMPLE_BAT = ROOT / "protocols" / "examples" / "sample-bat.toml"
TERMS = MetricTerms(k=0.021, v_bat=27.4, v_pitch=31.3, ball_cor=0.47)  # a BPF needs the ball COR

TOY = Metric(
    "toy",
    "TOY",
    "",
    "TOY = 2 e_A (a metric made up to show what adding one takes)",
    value=lambda e_a, t: 2.0 * e_a,
    e_a_of=lambda v, t: v / 2.0,
    limit_range=(0.0, 2.0),
    budget_output="e_a",
    u_scale=lambda t: 2.0,
    u_scale_text="dTOY/de_A = 2",
    cross_check=False,
)

TOY_PROCEDURE = """\
[procedure]
name = "Toy metric"
standard = "toy"
edition = "a test of the metric registry, no standard"
limit = 1.2
"""


def _cli(*args: str) -> tuple[int, str]:
    with contextlib.redirect_stdout(io.StringIO()) as out:
        code = main(list(args))
    return code, out.getvalue()


def _toy(e_a: float) -> float:
    """The toy formula, written apart from the registry entry."""
    return e_a + e_a


def test_a_toy_metric_is_a_registry_entry_and_a_procedure_file(tmp_path: Path) -> None:
    procedure = tmp_path / "toy.toml"
    procedure.write_text(TOY_PROCEDURE, encoding="utf-8")
    db = tmp_path / "records.db"
    with registry.registered(TOY):
        with rig.open_store(db) as store:
            result = rig.certify(
                bat=rig.Bat.load(SAMPLE_BAT), procedure=procedure, rig=rig.simulated("ideal"), store=store
            )
            record = run_record(store, result.run_id)
        code_md, md = _cli("report", result.run_id, "--db", str(db), "--format", "md")
        code_runs, runs = _cli("runs", "--db", str(db), "--json")
    assert registry.find("toy") is None and "toy" not in registry.DEFINITIONS  # the entry is gone again
    with pytest.raises(ConfigError, match="unknown metric 'toy'"):
        Procedure.load(procedure)

    assert result.status == "finished" and result.verdict is not None
    shots = [s for s in record["shots"] if s.get("metric") is not None]
    assert len(shots) >= 6
    for s in shots:  # each shot's metric is 2 e_A of its own speeds at the impact point
        e_a = s["rebound_at_impact_m_s"] / s["inbound_at_impact_m_s"]
        assert s["metrics"]["toy"] == s["metric"] == pytest.approx(_toy(e_a), rel=1e-12)
        assert s["u"] == pytest.approx(2.0 * s["budget"]["outputs"]["e_a"]["u"], rel=1e-12)
    verdict = record["verdict"]
    assert verdict["metric"] == "toy" and verdict["definition"] == TOY.definition
    assert verdict["mean"] == pytest.approx(sum(verdict["hits"]) / verdict["n_hits"], rel=1e-12)
    assert 0.2 < verdict["mean"] < 1.2 and result.verdict == rig.Verdict.PASS

    assert code_md == 0 and f"PASS: TOY {verdict['mean']:.3f}" in md
    assert "TOY: TOY = 2 e_A" in md and "dTOY/de_A = 2 = 2.00)" in md
    assert code_runs == 0
    (row,) = json.loads(runs)
    assert (row["run_id"], row["procedure"], row["verdict"]) == (result.run_id, "toy", "PASS")


def test_a_procedure_naming_an_unknown_metric_is_refused_in_one_line(tmp_path: Path) -> None:
    procedure = tmp_path / "bpf.toml"
    procedure.write_text(TOY_PROCEDURE.replace('"toy"', '"bpf"'), encoding="utf-8")
    with pytest.raises(ConfigError) as caught:
        Procedure.load(procedure)
    message = str(caught.value)
    assert "\n" not in message
    assert str(procedure) in message and "procedure.standard" in message
    assert "unknown metric 'bpf'; known: bbcor, besr, bbs" in message


def test_a_limit_outside_the_metrics_registry_range_is_refused(tmp_path: Path) -> None:
    procedure = tmp_path / "toy.toml"
    procedure.write_text(TOY_PROCEDURE.replace("limit = 1.2", "limit = 2.5"), encoding="utf-8")
    with registry.registered(TOY), pytest.raises(ConfigError, match=r"2.5 is outside \(0, 2\] for toy"):
        Procedure.load(procedure)


@pytest.mark.parametrize("name", registry.BUILTIN_METRICS)
def test_each_metric_formula_its_inverse_and_u_scale_agree(name: str) -> None:
    """The inverse undoes the formula; u_scale is d(metric)/d(budget output) (1 for the metric itself)."""
    m = registry.metric(name)
    for e_a in (0.05, 0.2, 0.37):
        value = m.value(e_a, TERMS)
        assert m.e_a_of is not None and m.e_a_of(value, TERMS) == pytest.approx(e_a, abs=1e-12)
    h = 1e-6
    slope = (m.value(0.2 + h, TERMS) - m.value(0.2 - h, TERMS)) / (2 * h)
    # u_scale = d(metric)/d(budget output) = d(metric)/de_A over d(output)/de_A (BBCOR's is 1 + k)
    d_output = {"e_a": 1.0, "besr": 1.0, "bbcor": 1.0 + TERMS.k}[m.budget_output]
    assert m.scale(TERMS) == pytest.approx(slope / d_output, rel=1e-6)
    if m.budget_output == name:
        assert m.scale(TERMS) == 1.0


@pytest.mark.parametrize("name", registry.cross_checked())
def test_a_cross_checked_metric_is_affine_in_e_a(name: str) -> None:
    """The calibration fits metric = alpha + beta e_A (rig.population.calibrate): it must be so."""
    m = registry.metric(name)
    ends = (m.value(0.0, TERMS) + m.value(1.0, TERMS)) / 2
    assert m.value(0.5, TERMS) == pytest.approx(ends, rel=1e-12)


def test_the_measurement_model_outputs_are_the_registry_formulas() -> None:
    """A metric the budget propagates as itself (bbcor, besr): the model's output is its formula."""
    shot = ShotInputs.ideal(60.8, 12.3, (0.9, 0.6, 0.3), 1e-8, 0.52, 0.19, 0.145)
    values = outputs(shot.vector(), shot.gates)
    e_a, k = values[OUTPUTS.index("e_a")], 0.145 * 0.52**2 / 0.19
    terms = MetricTerms(k=k, v_bat=0.0, v_pitch=0.0)
    direct = [m for m in registry.metrics() if m.budget_output == m.name]
    assert {m.name for m in direct} == {"bbcor", "besr"}
    for m in direct:
        assert values[OUTPUTS.index(m.name)] == pytest.approx(m.value(float(e_a), terms), rel=1e-12)


def test_compute_metrics_carries_a_registered_metric_and_definitions_follow() -> None:
    before = compute_metrics(60.8, 12.16, 0.56, 0.19, 0.145, 0.8382).as_dict()
    with registry.registered(TOY):
        m = compute_metrics(60.8, 12.16, 0.56, 0.19, 0.145, 0.8382, ball_cor=0.47)
        assert m.value("toy") == m.as_dict()["toy"] == pytest.approx(_toy(m.e_a))
        assert set(m.as_dict()) == set(registry.DEFINITIONS)
        # without the run's ball COR, the metrics divided by it (BPF) are not computed
        by_ball = {"ball_cor", *(x.name for x in registry.metrics() if x.needs_ball_cor)}
        plain = compute_metrics(60.8, 12.16, 0.56, 0.19, 0.145, 0.8382).as_dict()
        assert set(plain) == set(registry.DEFINITIONS) - by_ball and by_ball - {"ball_cor"}
        with pytest.raises(ConfigError, match="taken"):
            registry.register(TOY)
    assert compute_metrics(60.8, 12.16, 0.56, 0.19, 0.145, 0.8382).as_dict() == before
    with pytest.raises(ConfigError, match="not a registered metric"):
        registry.unregister("bbcor")


def test_a_registration_is_refused_when_the_budget_output_is_not_the_models() -> None:
    bad: dict[str, Any] = {"budget_output": "toy"}
    with pytest.raises(ConfigError, match="budget output 'toy'"):
        registry.register(Metric(**{**TOY.__dict__, **bad}))
    assert registry.find("toy") is None


def test_the_population_file_has_a_column_for_each_cross_checked_metric() -> None:
    """rig model calibrate fits a population column: a metric the cross-check supports has one, or
    (a BPF, a USA Softball BBS) is fitted on the runs' BBCOR column and predicted through e_A."""
    from rig.population.calibrate import fitted_quantity

    assert set(METRICS) <= set(registry.cross_checked())
    assert {fitted_quantity(m) for m in registry.cross_checked()} == set(METRICS)
    assert {m for m in registry.cross_checked() if m not in METRICS} == {
        "usas_bbs_2004",
        "usas_bbs_2012",
        "usssa_bpf",
        "fastpitch_bpf",
    }
    with registry.registered(TOY):
        assert "toy" not in registry.cross_checked()


def test_a_calibration_file_names_only_a_metric_the_cross_check_supports(tmp_path: Path) -> None:
    """The file's metric is checked against the registry: a registered toy without the cross-check
    is refused in one line naming the field, the example population's bbcor file loads."""
    from rig.population import load_population
    from rig.population.calfile import calibration_record, load_calibration, write_calibration
    from rig.population.calibrate import calibrate

    population = load_population(ROOT / "protocols" / "examples" / "population.csv")
    record = calibration_record(calibrate(population, variants=("m2+c2",)), b"x", "pop.csv")
    assert load_calibration(write_calibration(record, tmp_path / "cal.json")).metric == "bbcor"
    with registry.registered(TOY), pytest.raises(ConfigError) as caught:
        write_calibration({**record, "metric": "toy"}, tmp_path / "toy.json")
    assert "\n" not in str(caught.value)
    assert "metric: Value error, the model cross-check does not support 'toy'" in str(caught.value)

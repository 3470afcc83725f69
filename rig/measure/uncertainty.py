"""GUM uncertainty of one hit's or one bat's results, with correlations, and a Monte Carlo check.

The measurement function and input distributions are in rig.measure.model. The inputs are
independent, so the outputs' covariance is J diag(u^2) J^T and each input's variance share adds
up; the Jacobian is taken by complex step (exact to rounding, no step-size choice). Correlations
come from shared inputs: the same gates time inbound and rebound, so their spacing cancels in e_A.
Per bat (mean of n hits) the shared inputs enter once, so u(mean) has a floor: it does not fall
as 1/sqrt(n). See docs/measurement.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.core.errors import ParameterError
from rig.measure.model import (
    DEFAULT_MODEL,
    OUTPUTS,
    SHARED,
    ShotInputs,
    Spread,
    UncertaintyModel,
    input_u,
    jacobian,
    outputs,
    values_and_jacobian,
)

__all__ = [
    "DEFAULT_MODEL",
    "OUTPUTS",
    "Budget",
    "MonteCarlo",
    "ShotInputs",
    "Spread",
    "UncertaintyModel",
    "budget",
    "jacobian",
    "monte_carlo",
    "u_with_scatter",
]


@dataclass(frozen=True)
class Budget:
    """Linear (GUM) uncertainty of the results of one hit, or of the mean of `n_hits` hits."""

    outputs: tuple[str, ...]
    values: tuple[float, ...]
    covariance: np.ndarray  # outputs x outputs
    inputs: tuple[str, ...]
    input_u: tuple[float, ...]  # standard uncertainty of each input (one crossing, for times)
    systematic: tuple[bool, ...]  # shared by every hit on the bat
    contributions: np.ndarray  # outputs x inputs: variance due to each input; rows sum to u^2
    n_hits: int
    coverage_k: float

    @property
    def u(self) -> np.ndarray:
        """Standard uncertainty of each output."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def correlation(self) -> np.ndarray:
        """Correlation matrix of the outputs."""
        u = self.u
        with np.errstate(invalid="ignore", divide="ignore"):
            r = self.covariance / np.outer(u, u)
        return np.where(np.outer(u, u) > 0.0, r, np.eye(len(u)))

    def _row(self, output: str) -> int:
        if output not in self.outputs:
            raise ParameterError("output", output, f"not one of {self.outputs}")
        return self.outputs.index(output)

    def value(self, output: str) -> float:
        """The output's value (mean over the hits)."""
        return self.values[self._row(output)]

    def u_of(self, output: str) -> float:
        """Standard uncertainty of one output."""
        return float(self.u[self._row(output)])

    def expanded(self, output: str) -> float:
        """Expanded uncertainty U = k u."""
        return self.coverage_k * self.u_of(output)

    def systematic_variance(self, output: str) -> float:
        """Variance from inputs shared by every hit (does not average down)."""
        return float(self.contributions[self._row(output)][np.array(self.systematic)].sum())

    def random_variance(self, output: str) -> float:
        """Variance from inputs independent per hit (falls as 1/n)."""
        return float(self.contributions[self._row(output)][~np.array(self.systematic)].sum())

    def ranked(self, output: str) -> list[tuple[str, float]]:
        """(input, share of the output's variance), largest first."""
        row = self.contributions[self._row(output)]
        total = row.sum()
        shares = row / total if total > 0 else row
        return sorted(zip(self.inputs, shares.tolist(), strict=True), key=lambda p: -p[1])

    def as_dict(self) -> dict[str, object]:
        """Plain values for the store and the report."""
        return {
            "n_hits": self.n_hits,
            "coverage_k": self.coverage_k,
            "outputs": {
                name: {
                    "value": self.values[i],
                    "u": float(self.u[i]),
                    "U": self.coverage_k * float(self.u[i]),
                    "random_variance": self.random_variance(name),
                    "systematic_variance": self.systematic_variance(name),
                    "contributions": dict(self.ranked(name)),
                }
                for i, name in enumerate(self.outputs)
            },
            "inputs": {
                n: {"u": u, "systematic": s}
                for n, u, s in zip(self.inputs, self.input_u, self.systematic, strict=True)
            },
            "correlation": self.correlation.tolist(),
        }


def _check_shared(shots: Sequence[ShotInputs]) -> None:
    if not shots:
        raise ParameterError("shots", [], "need at least one hit")
    first = shots[0].shared()
    for i, s in enumerate(shots[1:], start=2):
        if s.shared() != first:
            raise ParameterError(
                "shots", i, "gate positions, Q, I and ball mass must be the same for every hit"
            )


def budget(shots: ShotInputs | Sequence[ShotInputs], model: UncertaintyModel = DEFAULT_MODEL) -> Budget:
    """GUM budget of one hit, or of the mean of several hits on one bat (shared inputs propagated jointly)."""
    hits = [shots] if isinstance(shots, ShotInputs) else list(shots)
    _check_shared(hits)
    n = len(hits)
    cols: list[np.ndarray] = []  # sensitivity x u, per column
    names: list[str] = []
    unit_u: dict[str, float] = {}
    shared_ju = np.zeros((len(OUTPUTS), len(SHARED)))
    values = np.zeros(len(OUTPUTS))
    for hit in hits:
        value, J = values_and_jacobian(hit)
        u, hit_names = input_u(hit, model), hit.names()
        values += value / n
        for j in range(4):  # timing: independent per hit, each enters the mean with weight 1/n
            cols.append(J[:, j] * u[j] / n)
            names.append(hit_names[j])
            unit_u[hit_names[j]] = float(u[j])
        shared_ju += J[:, 4:] * u[4:] / n  # shared: sensitivities of the mean add, then propagate once
    u_shared = input_u(hits[0], model)[4:]
    for j, name in enumerate(SHARED):
        cols.append(shared_ju[:, j])
        names.append(name)
        unit_u[name] = float(u_shared[j])
    JU = np.column_stack(cols)
    order = list(dict.fromkeys(names))
    if len(order) == len(names):  # one hit: every column is its own input
        contrib = JU**2
    else:
        contrib = np.column_stack(
            [sum(JU[:, i] ** 2 for i, nm in enumerate(names) if nm == key) for key in order]
        )
    return Budget(
        outputs=OUTPUTS,
        values=tuple(float(v) for v in values),
        covariance=JU @ JU.T,
        inputs=tuple(order),
        input_u=tuple(unit_u[k] for k in order),
        systematic=tuple(k in SHARED for k in order),
        contributions=contrib,
        n_hits=n,
        coverage_k=model.coverage_k,
    )


@dataclass(frozen=True)
class MonteCarlo:
    """Monte Carlo (JCGM 101) propagation of the same input distributions."""

    outputs: tuple[str, ...]
    mean: np.ndarray
    covariance: np.ndarray
    draws: int

    @property
    def u(self) -> np.ndarray:
        """Standard deviation of each output over the draws."""
        return np.sqrt(np.diag(self.covariance))

    @property
    def correlation(self) -> np.ndarray:
        """Correlation matrix of the outputs over the draws."""
        return self.covariance / np.outer(self.u, self.u)


def monte_carlo(
    shots: ShotInputs | Sequence[ShotInputs],
    model: UncertaintyModel = DEFAULT_MODEL,
    draws: int = 100_000,
    rng: np.random.Generator | int | None = 0,
    chunk: int = 25_000,
) -> MonteCarlo:
    """Draw every input from its distribution (shared inputs once per draw) and evaluate the results."""
    hits = [shots] if isinstance(shots, ShotInputs) else list(shots)
    _check_shared(hits)
    gen = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
    results = []
    for start in range(0, draws, chunk):
        N = min(chunk, draws - start)
        shared = np.column_stack(
            [
                model.gate_position.sample(gen, (N, 3)),
                model.gate_delay.sample(gen, (N, 3)),
                model.impact_q.sample(gen, (N,)),
                hits[0].moi_kgm2 * model.moi_relative.sample(gen, (N,)),
                model.ball_mass.sample(gen, (N,)),
                model.drag_in.sample(gen, (N,)),
                model.drag_out.sample(gen, (N,)),
                model.air_density.sample(gen, (N,)),
            ]
        )
        total = np.zeros((N, len(OUTPUTS)))
        for hit in hits:
            p = np.broadcast_to(hit.vector(), (N, len(hit.vector()))).copy()
            p[:, 4:] += shared
            half = hit.tick_s / 2.0
            p[:, :4] += gen.uniform(-half, half, (N, 4)) + model.trigger_jitter.sample(gen, (N, 4))
            total += outputs(p, hit.gates, hit.ball_diameter_m)
        results.append(total / len(hits))
    y = np.concatenate(results)
    return MonteCarlo(OUTPUTS, y.mean(axis=0), np.cov(y, rowvar=False), draws)


def u_with_scatter(per_bat: Budget, hit_values: Sequence[float], output: str = "bbcor") -> float:
    """u of a bat's mean combining the hits' observed scatter (Type A) with the systematic part.

    The scatter of the n hits holds the timing noise and what the model leaves out (ball-to-ball
    COR, impact-point and speed scatter), so s^2/n stands in for the modelled random variance,
    but never below it: u^2 = max(s^2/n, u_random^2) + u_systematic^2.
    """
    n = len(hit_values)
    if n != per_bat.n_hits or n < 2:
        raise ParameterError(
            "hit_values", n, f"need one value per hit of the budget ({per_bat.n_hits}), >= 2"
        )
    type_a = float(np.var(np.asarray(hit_values, dtype=float), ddof=1)) / n
    return float(np.sqrt(max(type_a, per_bat.random_variance(output)) + per_bat.systematic_variance(output)))

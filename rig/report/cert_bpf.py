"""The certificate's BPF section: the pivoted BBCOR, the ball COR with its lot and u, and BPF with U.

From the record alone: the verdict's `bpf` (rig.protocols.verdict.bpf_part) and the procedure's
basis. A run of another metric shows only the basis its metric assumes, where the registry states
one (ASTM F1890-23 pivoted, F2219-23 unconstrained: rig.measure.bpf).
"""

from __future__ import annotations

from typing import Any

from rig.measure import registry
from rig.measure.bpf import UNCONSTRAINED
from rig.report.cert_doc import Block, Heading, Para, kv


def _n(x: Any, digits: int = 4) -> str:
    return "—" if not isinstance(x, int | float) else f"{x:.{digits}f}"


def basis_rows(record: dict[str, Any]) -> list[tuple[str, str]]:
    """('basis', ...) for a metric whose registry entry states the bat's constraint, else nothing; a
    pivoted one says it is not F2219-23's unconstrained formula (the cannon method is F2219's)."""
    entry = registry.find(
        (record.get("verdict") or {}).get("metric") or (record.get("procedure") or {}).get("standard")
    )
    if entry is None or not entry.basis:
        return []
    if not entry.basis.startswith("pivoted"):
        return [("basis (the bat's constraint)", entry.basis)]
    other = UNCONSTRAINED if "BBCOR" in entry.basis else "unconstrained (ASTM F2219-23: the free bat's)"
    return [("basis (the bat's constraint)", f"{entry.basis}; not {other}")]


def _cor_rows(b: dict[str, Any], k: float) -> list[tuple[str, str]]:
    """The lot's COR as its test measured it, what moved it to the lot's nominal ball, and its u."""
    found = b.get("ball_cor_measured")
    w: dict[str, Any] = found if isinstance(found, dict) else {}
    cor, u_cor = b.get("ball_cor"), b.get("ball_cor_u")
    run = str(b.get("ball_cor_run") or "")
    expanded = None if not isinstance(u_cor, int | float) else k * u_cor
    air = w.get("air_correction")
    rows = [
        (
            "ball COR measured (rigid flat wall, 60 mph)",
            f"{_n(w.get('measured'))} (u {_n(w.get('u_test'), 5)}, its test's) of lot {b.get('lot') or '—'}, "
            f"ball-cor run {run[:12] or '—'}",
        ),
        (
            "to a new ball (the lot's wear per hit)",
            f"{_signed(w.get('wear_correction'))} (u {_n(w.get('u_wear'), 5)})",
        ),
        (
            "to the lot's nominal air",
            f"{_signed(air)} (u {_n(w.get('u_air'), 5)})"
            + ("" if air else ": not moved, the air's sensitivities are assumed; the whole effect budgeted"),
        ),
    ]
    rows.append(
        (
            "ball COR of a new ball at the nominal air (the divisor)",
            f"{_n(cor)} (u {_n(u_cor, 5)}, U {_n(expanded, 5)}, k = {k:g})",
        )
    )
    return rows


def _signed(x: Any, digits: int = 5) -> str:
    return "—" if not isinstance(x, int | float) else f"{x:+.{digits}f}"


def bpf_blocks(record: dict[str, Any]) -> list[Block]:
    """The BPF's parts, for a BPF run with a verdict (else nothing)."""
    v = record.get("verdict") or {}
    b = v.get("bpf")
    if not isinstance(b, dict):
        return []
    k = v.get("coverage_k", 2.0)
    mean, big_u, limit = v.get("mean"), v.get("U"), v.get("limit")
    shared = [
        ("u shared: the air's sensitivities (hits and COR, one term)", _n(b.get("u_shared_air"), 5)),
        ("u shared: the wear per hit (hits and COR, one term)", _n(b.get("u_shared_wear"), 5)),
    ]
    return [
        Heading("Bat performance factor"),
        kv(
            [
                ("basis", f"{b.get('basis', '—')}; not {UNCONSTRAINED}"),
                (
                    "BBCOR (pivoted), mean of the valid hits, each corrected to the lot's nominal ball",
                    f"{_n(b.get('bbcor_mean'))} (u {_n(b.get('u_bbcor'), 5)}, n = {v.get('n_hits')}; "
                    "section Balls)",
                ),
                *_cor_rows(b, k),
                ("BPF = BBCOR / ball COR", f"{_n(mean)} ± {_n(big_u)} (U, k = {k:g})"),
                (
                    "u from the hits alone (their budget, scatter, ball spread, g) / COR",
                    _n(b.get("u_from_bbcor"), 5),
                ),
                ("u from the COR's test (BPF u(COR) / COR)", _n(b.get("u_from_ball_cor"), 5)),
                *(shared if "u_shared_air" in b else []),
                ("u of the BPF (these combined)", _n(v.get("u"), 5)),
                ("limit", str(limit)),
                ("verdict", f"{v.get('verdict')} ({v.get('zone', '—')})"),
            ]
        ),
        Para(
            "The ball COR is one value of the lot, divided into every hit: the u of its test is fully "
            "correlated across the hits and enters the mean once, not divided by the square root of their "
            "number. The hits and the COR are both taken to the lot's nominal ball (a new ball at its "
            "conditioning air): the wear per hit (measured on the lot) corrects both; the air corrects "
            "both where the lot's sensitivities were measured, else neither, its whole effect budgeted. "
            "A sensitivity moves the hits and the COR together, so its u is one term of the BPF: "
            "u = |g d_hits - BPF d_COR| u(s) / COR, d each side's offset from the nominal (g = "
            "dBBCOR/d(plate COR), section Balls)."
            if "u_shared_air" in b
            else "The ball COR is one value of the lot, divided into every hit: its u is fully correlated "
            "across the hits and enters the mean once, not divided by the square root of their number "
            "(a record made before the shared terms: the hits' and the COR's ball terms in quadrature)."
        ),
    ]

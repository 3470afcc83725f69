"""The balls of a certification: a qualified lot from the store, its rules checked, its terms for the verdict.

`rig certify --ball-lot LOT [--ball BALL.json]` names the lot the run's balls come from. Before
anything is armed the lot must be registered (`rig balls register`), qualified (at least one
ball-cor test, meeting the lot's specification where it states one), conditioned as long as the
procedure asks, and the ball law (if given) fitted on this lot or on none named. The run then
records the lot's terms (rig.protocols.ball_terms) in RunStarted, starting on the lot's first ball no
earlier run fired; the procedure enforces the rest at each shot (the lab's air within the
conditioning window, balls numbered within the lot).
"""

from __future__ import annotations

from typing import Any

from rig.core import events as ev
from rig.core.ball import BallLot, LotResult
from rig.core.errors import ConfigError
from rig.protocols.ball_terms import BallTerms, terms_from_lot
from rig.protocols.procedure import Ball, Procedure


def qualify(
    lot: BallLot, results: list[LotResult], procedure: Procedure, store: Any = None
) -> list[LotResult]:
    """The lot's ball-cor results a certification may rest on; ConfigError names what is missing.

    With `store`, the latest test must have fired the procedure's balls (same_balls) before its COR
    is held against the lot's specification: another ball's COR failing it says nothing of the lot."""
    cor = [r for r in results if r.procedure == "ball-cor"]
    where = f"--ball-lot {lot.id}"
    if not cor:
        raise ConfigError(
            f"lot {lot.id} is not qualified: no ball-cor test; run "
            f"'{which_test(procedure.ball.ball_class)} --lot {lot.id}' first",
            source=where,
        )
    latest = cor[-1]
    if store is not None:
        same_balls(store, lot.id, latest.run_id, procedure)
    if lot.meets(latest.quantity, latest.mean, latest.U) is False:
        nominal = lot.specification.nominal_cor
        raise ConfigError(
            f"lot {lot.id} fails its specification: COR {latest.mean:.4f} (U {latest.U:.4f}) against "
            f"{nominal} +- {lot.specification.cor_tolerance} (ball-cor run {latest.run_id[:12]})",
            source=where,
        )
    need = procedure.ball.conditioning_days_min
    days = lot.conditioning.days
    if need is not None and (days is None or days < need):
        stated = "states no conditioning days" if days is None else f"was conditioned {days:g} days"
        raise ConfigError(
            f"lot {lot.id} {stated}; the procedure asks at least {need:g} ([lot.conditioning] days)",
            source=where,
        )
    return cor


BALL_MASS_REL_TOL = 0.05  # [U] a ball test's nominal mass within 5 % of the procedure's: the same ball


def same_balls(store: Any, lot_id: str, run_id: str, procedure: Procedure) -> None:
    """The lot's latest ball-cor test must have fired the balls `procedure` names: the same class
    (a softball's COR/compression, none for a baseball) and nominal mass; else one ConfigError.

    Its COR (a BPF divides by it), wear and spread are those balls' own: another ball's would be
    silently wrong. What the test fired is its RunStarted procedure's [procedure.ball]."""
    started = store.entries(run_id, kinds=[ev.RUN_STARTED])
    tested = ((started[0].payload.get("procedure") or {}).get("ball") or {}) if started else {}
    ours = procedure.ball
    theirs_class = str(tested.get("ball_class") or "").lstrip(".") or None
    ours_class = (ours.ball_class or "").lstrip(".") or None
    mass = tested.get("mass_kg")
    if (
        theirs_class != ours_class
        or not isinstance(mass, int | float)
        or (abs(mass - ours.mass_kg) > BALL_MASS_REL_TOL * ours.mass_kg)
    ):
        raise ConfigError(
            f"lot {lot_id}'s ball-cor test (run {run_id[:12]}) fired balls of "
            f"{_balls(theirs_class, mass)}; {procedure.name} names "
            f"{_balls(ours_class, ours.mass_kg)}: test the lot with the procedure's balls "
            f"({which_test(ours_class)})",
            source=f"--ball-lot {lot_id}",
        )


def which_test(ball_class: str | None) -> str:
    """The built-in ball-cor test firing balls of `ball_class` (None: baseballs, no class), or how to
    write one; from the built-in ball tests (rig.protocols.names.BALL_BUILTIN)."""
    wanted = (ball_class or "").lstrip(".") or None
    for name, test in _builtin_tests():
        if test.test == "ball-cor" and ((test.ball.ball_class or "").lstrip(".") or None) == wanted:
            return f"rig balls test --procedure {name}"
    return f'a ball-cor TOML file with [procedure.ball] ball_class = "{ball_class}"'


def _builtin_tests() -> list[tuple[str, Any]]:
    from rig.protocols.ball_procedure import BallProcedure
    from rig.protocols.names import BALL_BUILTIN

    return [(name, BallProcedure.load(name)) for name in BALL_BUILTIN]


def tests_for_lot(lot: BallLot) -> list[str]:
    """The built-in ball tests whose balls the lot's registration allows (balls_mismatch)."""
    return [name for name, test in _builtin_tests() if balls_mismatch(lot, test.ball) is None]


def balls_mismatch(lot: BallLot, ball: Ball) -> str | None:
    """Why balls `ball` (a procedure's [procedure.ball]) are not the lot's as registered: its mass
    more than BALL_MASS_REL_TOL from the lot's mass_kg, or (a softball's class COR/compression) a
    COR outside the lot's nominal_cor +- its tolerance (0.01 if none) or a compression more than
    5 % from its compression_lbf; None where the registration allows them (or states nothing)."""
    spec, found = lot.specification, []
    if spec.mass_kg is not None and abs(spec.mass_kg - ball.mass_kg) > BALL_MASS_REL_TOL * ball.mass_kg:
        found.append(f"mass {spec.mass_kg:g} kg")
    key = (ball.ball_class or "").lstrip(".")
    if key:
        cor, compression = int(key[:2]) / 100.0, float(key[3:])
        tolerance = spec.cor_tolerance if spec.cor_tolerance is not None else 0.01
        if spec.nominal_cor is not None and abs(spec.nominal_cor - cor) > tolerance + 1e-9:
            found.append(f"COR {spec.nominal_cor:g}")
        if spec.compression_lbf is not None and abs(spec.compression_lbf - compression) > 0.05 * compression:
            found.append(f"compression {spec.compression_lbf:g} lbf")
    return " and ".join(found) or None


def refuse_other_balls(lot: BallLot, name: str, ball: Ball) -> None:
    """ConfigError (one line) if the ball test `name` fires balls `ball` the lot is not registered as."""
    found = balls_mismatch(lot, ball)
    if found is None:
        return
    fits = tests_for_lot(lot)
    advice = (
        "test it with " + " or ".join(f"rig balls test --procedure {n}" for n in fits)
        if fits
        else "give a ball test whose [procedure.ball] are the lot's balls"
    )
    raise ConfigError(
        f"lot {lot.id} is registered with {found}; {name} fires balls of "
        f"{_balls((ball.ball_class or '').lstrip('.') or None, ball.mass_kg)}: {advice}",
        source="--lot",
    )


def _balls(ball_class: str | None, mass: Any) -> str:
    return (
        f"{'class ' + ball_class if ball_class else 'no ball class'}, {mass if mass is not None else '?'} kg"
    )


def lot_terms(
    store: Any,
    lot_id: str,
    procedure: Procedure,
    law: Any = None,
    law_sha256: str | None = None,
    law_file: str | None = None,
) -> BallTerms:
    """The ball terms of registered lot `lot_id` for a certification with `procedure`.

    `law`: a rig.physics.ball_law.BallLaw (`--ball`, the file's sha256 `law_sha256`), refused if
    it was fitted on another lot; without it, the lot's recorded ball law if it has one.
    """
    lot, results = store.ball_lot(lot_id)
    cor = qualify(lot, results, procedure, store)
    law_from = f"--ball {law_file}" if law_file else "--ball"
    if law is None:
        recorded = lot_law(store, lot_id)
        if recorded is not None:
            law, law_sha256 = recorded
            law_from = f"lot {lot_id}'s recorded law"
    if law is not None and law.lot not in (None, lot.id):
        raise ConfigError(
            f"the ball law was fitted on lot {law.lot}, not {lot.id}: fit one on this lot "
            f"('rig model fit-ball --db STORE --lot {lot.id}') or name its lot",
            source="--ball",
        )
    constants = None if law is None else dict(law.constants)
    terms = terms_from_lot(lot, cor, constants)
    first = first_unused_ball(store, lot)
    need = balls_needed(procedure)
    if lot.balls - first + 1 < need:
        raise ConfigError(
            f"lot {lot.id} has {max(0, lot.balls - first + 1)} of its {lot.balls} balls never fired; "
            f"this procedure needs at least {need} (a new ball after "
            f"{procedure.ball.replace_after_hits} hits)",
            source=f"--ball-lot {lot.id}",
        )
    named = {} if law is None else {"law_sha256": law_sha256, "law_from": law_from}
    return terms.model_copy(update={"balls": lot.balls, "first_ball": first, **named})


def record_lot_law(store: Any, lot_id: str, path: str) -> tuple[Any, str]:
    """Record the ball file at `path` as lot `lot_id`'s ball law (its exact text); (entry, sha256).

    Refused (ConfigError) if the file is not a ball law, or was fitted on another lot or on none.
    """
    from rig.physics.ball_law import BallLaw

    law, raw = BallLaw.read_file(path)  # read once: what is checked is what is recorded
    if law.lot != lot_id:
        fitted = f"lot {law.lot}" if law.lot else "no lot"
        raise ConfigError(f"the ball law was fitted on {fitted}, not lot {lot_id}", source=str(path))
    entry = store.record_ball_law(lot_id, raw.decode("utf-8"))  # parse_bytes checked it is UTF-8
    return entry, str(entry.payload["sha256"])


def lot_law(store: Any, lot_id: str) -> tuple[Any, str] | None:
    """The lot's latest recorded ball law (rig.physics.ball_law.BallLaw, its sha256), None if none."""
    from rig.physics.ball_law import BallLaw

    recorded = store.ball_laws(lot_id)
    if not recorded:
        return None
    last = recorded[-1]
    source = f"lot {lot_id}'s recorded ball law (entry {last.seq})"
    if not last.intact:
        raise ConfigError("its text does not match its recorded sha256", source=source)
    return BallLaw.parse_text(last.text, source), last.sha256


def first_unused_ball(store: Any, lot: BallLot) -> int:
    """The number of the lot's first ball after every ball any recorded shot fired (1 if none).

    A certification starts on balls no earlier run has hit, so each ball's recorded hit count is
    its whole history (a ball's wear does not reset between runs)."""
    prefix, highest = f"{lot.id}-", 0
    for entry in store.entries(kinds=[ev.SHOT_FIRED]):
        ball = str(entry.payload.get("ball") or "")
        if ball.startswith(prefix) and ball[len(prefix) :].isdigit():
            highest = max(highest, int(ball[len(prefix) :]))
    return highest + 1


def balls_needed(procedure: Procedure) -> int:
    """The fewest balls a run of `procedure` can need: its scan and valid hits, no re-shot."""
    shots = len(procedure.scan.locations_in()) * procedure.scan.hits_per_location + procedure.hits.valid_hits
    return -(-shots // procedure.ball.replace_after_hits)


def law_terms(law: Any, sha256: str | None = None, law_file: str | None = None) -> BallTerms:
    """The terms of a run that names a ball law but no lot: the law recorded, the rest assumed."""
    return BallTerms(
        law=dict(law.constants),
        law_sha256=sha256,
        law_from=None if sha256 is None else (f"--ball {law_file}" if law_file else "--ball"),
        source="ball law given, no lot named: assumed defaults [U]",
    )

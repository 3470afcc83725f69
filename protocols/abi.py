"""The NCAA accelerated break-in (ABI) as a plan: the rules of rig.protocols.abi_rules on a recorded run.

Run with the BBCOR procedure and this plan (`rig.certify(..., plan=abi)`): the standard opening
(start, air, stage, MOI), then what `next_step` says from the record: barrel compression at 6 in
(CompressionMeasured), the BBCOR of the new bat (the standard scan, location and valid hits),
an inspection, then stages of rolling (the operator reports each step: BarrelRolled) until the
compression has dropped enough, the stage's BBCOR (valid hits `abi-<stage>` at the chosen location:
AbiStageMeasured, with the cross-check at the stage's hoop frequency where measured) and an
inspection, until the bat exceeds the limit, shows damage or is broken in. Every decision reads the
folded record, so an interrupted run resumes where it stopped.
"""

from __future__ import annotations

from dataclasses import replace

from rig.core import events as ev
from rig.core.outcomes import RunVerdict, Verdict
from rig.protocols.abi_rules import (
    AbiRules,
    Compressed,
    Inspected,
    Measured,
    Recorded,
    Rolled,
    next_step,
    stages,
)
from rig.protocols.plan import (
    Ask,
    AskRolling,
    Checkpoint,
    DecideStage,
    MeasureCompression,
    Plan,
    PlanContext,
    Problem,
    Record,
)
from rig.protocols.state import RunState
from rig.protocols.steps import choose_location, opening, scan, shoot, valid_hits

ROLE = "barrel-compression-tester"  # the equipment register's item an ABI run needs (EQUIPMENT_ROLES)
INSPECTION = (
    "Inspect the barrel: is it free of damage (no crack, delamination, dent, rattle or loose part)? "
    "n ends the break-in"
)


def rules_of(ctx: PlanContext) -> AbiRules:
    """The run's ABI rules: its options' `abi` table, else the built-in protocols/abi.toml."""
    given = ctx.options.get("abi")
    return AbiRules.model_validate(given) if given is not None else AbiRules.load()


def purpose_of(stage: int) -> str:
    """The shots of a stage: the new bat's are the standard valid hits, later ones `abi-<stage>`."""
    return "valid" if stage == 0 else f"abi-{stage}"


def history(state: RunState) -> list[Recorded]:
    """The break-in's record as the rules read it."""
    out: list[Recorded] = []
    for noted in state.abi:
        d = noted.data
        if noted.kind == ev.COMPRESSION_MEASURED:
            out.append(Compressed(float(d["force_lbf"])))
        elif noted.kind == ev.BARREL_ROLLED:
            out.append(Rolled(float(d["depth_in"]), int(d["passes"]), str(d.get("who") or "")))
        elif noted.kind == ev.ABI_STAGE_MEASURED:
            result = d["result"]
            out.append(Measured(float(result["mean"]), float(result.get("U") or 0.0), d.get("hoop_hz")))
        else:  # the inspection: the barrel is free of damage (yes) or not
            out.append(Inspected(damaged=not bool(d["answer"])))
    return out


def stage_hoop(ctx: PlanContext, stage: int) -> float | None:
    """The barrel's hoop frequency at a stage, where measured: the bat file's for the new bat, then
    the one the operator measured after the last rolling up to this stage (None: it was rolled and
    not measured since)."""
    hoop = ctx.bat.hoop_hz
    for n in ctx.state.abi:
        if n.kind == ev.BARREL_ROLLED and int(n.data["stage"]) <= stage:
            measured = n.data.get("hoop_hz")
            hoop = None if measured is None else float(measured)
    return hoop


def stage_bbcor(ctx: PlanContext, stage: int) -> Plan[None]:
    """The stage's BBCOR: the new bat's by the standard scan and valid hits, later ones at its location."""
    purpose = purpose_of(stage)
    if stage == 0:
        yield from scan(ctx)
        if ctx.state.best_location_in is None:
            yield from choose_location(ctx)
        yield from valid_hits(ctx)
    else:
        best = ctx.state.best_location_in
        assert best is not None, "a later stage follows the new bat's location"
        while len(ctx.state.valid_shots(purpose, best)) < ctx.procedure.hits.valid_hits:
            yield from shoot(ctx, best, purpose)
    hoop = stage_hoop(ctx, stage)
    result: RunVerdict = yield DecideStage(purpose, hoop)
    yield Record(ev.AbiStageMeasured(stage=stage, result=result.to_payload(), hoop_hz=hoop))


def abi(ctx: PlanContext) -> Plan[RunVerdict | None]:
    """The accelerated break-in of a composite bat to its verdict."""
    if ctx.state.finished:
        return ctx.state.verdict
    rules = rules_of(ctx)
    if ctx.config.devices.compression is None:  # found by the dry run, before anything is recorded
        yield Problem(
            "the accelerated break-in needs a barrel-compression tester: name one in the rig config "
            "([devices.compression], docs/instruments.md)"
        )
    if not any(item.role == ROLE for item in ctx.config.equipment):
        yield Problem(
            f"the accelerated break-in needs the role {ROLE} in the rig's equipment register "
            f'([[equipment]] with role = "{ROLE}", its calibration dates; docs/instruments.md)'
        )
    yield from opening(ctx)
    while True:
        yield Checkpoint()
        done = history(ctx.state)
        stage = len(stages(done)) - 1
        step = next_step(done, rules, ctx.procedure.limit)
        if step.action == "end":
            break
        if step.action == "compress":
            reading = yield MeasureCompression()
            yield Record(
                ev.CompressionMeasured(
                    stage=stage,
                    force_lbf=reading.force_lbf,
                    displacement_in=reading.displacement_in,
                    location_in=rules.location_in,
                )
            )
        elif step.action == "roll":
            n = sum(isinstance(x, Rolled) for x in done) + 1
            text = (
                f"Roll the barrel: {step.passes} passes at {step.depth_in:g} in depth (stage {stage}, "
                f"step {n}); report depth, passes and who rolled (and the hoop frequency if tapped)"
            )
            yield AskRolling(f"abi-roll-{n}", text, stage, step.depth_in, step.passes)
        elif step.action == "bbcor":
            yield from stage_bbcor(ctx, stage)
        else:
            yield Ask(f"{ev.ABI_DAMAGE_PROMPT}{stage}", INSPECTION)
    verdict = final_verdict(ctx.state, step.reason)
    yield Record(ev.RunFinished(result=verdict))
    return verdict


def stage_results(state: RunState) -> list[tuple[int, RunVerdict]]:
    """Each measured stage's verdict, in order."""
    return [
        (int(n.data["stage"]), RunVerdict.from_payload(n.data["result"], n.kind))
        for n in state.abi
        if n.kind == ev.ABI_STAGE_MEASURED
    ]


def final_verdict(state: RunState, why: str) -> RunVerdict:
    """The verdict after break-in: FAIL if any stage failed (the first such stage's result), else
    PASS with the last stage's; the reason says how the break-in ended."""
    results = stage_results(state)
    failed = [(s, r) for s, r in results if r.verdict is Verdict.FAIL]
    stage, deciding = failed[0] if failed else results[-1]
    rolled = len({n.data["stage"] for n in state.abi if n.kind == ev.BARREL_ROLLED})
    return replace(
        deciding,
        verdict=Verdict.FAIL if failed else Verdict.PASS,
        reason=f"after accelerated break-in ({rolled} rolled stages; stage {stage} decides): {why}",
    )

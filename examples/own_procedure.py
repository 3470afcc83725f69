"""A lab's own procedure from the standard steps: a screening check at one impact point (docs/api.md).

    python examples/own_procedure.py [RECORDS.db]

No location scan: the valid hits are taken 6 in from the tip, with the lab's air checked before
each one. The run is rehearsed against checking fakes first, then executed with the same run
control, records and resume as the standard procedure; its record names this plan. Prints the
verdict, the mean, the expanded uncertainty and the run id; exit status as certify_simulated.py.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Any

import rig
from rig import plans

SAMPLE_BAT = Path(__file__).resolve().parents[1] / "protocols" / "examples" / "sample-bat.toml"
AT_IN = 6.0  # inches from the tip


def screening(ctx: plans.PlanContext) -> plans.Plan[dict[str, Any]]:
    """Valid hits at AT_IN only, the lab's air checked before each; then the standard verdict."""
    if ctx.state.finished:
        return ctx.state.verdict
    yield from plans.preflight(ctx)
    yield from plans.start(ctx)
    yield from plans.check_budget(ctx)
    yield from plans.prepare(ctx)
    yield from plans.resolve_pending(ctx)  # a resumed run: a shot left unresolved is lost
    if ctx.state.moi is None:
        yield from plans.measure_moi(ctx)
    if ctx.state.best_location_in is None:
        chosen = plans.events.LocationChosen(from_barrel_end_in=AT_IN, bracketed=False)
        yield plans.Record(chosen)
    while len(ctx.state.valid_shots("valid", AT_IN)) < ctx.procedure.hits.valid_hits:
        yield from plans.environment(ctx)
        yield from plans.shoot(ctx, AT_IN, "valid")
    yield plans.Checkpoint()
    return (yield from plans.decide(ctx))


def main(db: Path) -> int:
    """Screen the sample bat on the simulated lab rig, recording in `db`; print the outcome."""
    with rig.open_store(db) as store:
        result = rig.certify(
            bat=rig.Bat.load(SAMPLE_BAT),
            procedure="bbcor",
            rig=rig.simulated("lab"),
            store=store,
            plan=screening,
        )
    if not result.finished:
        print(f"run {result.run_id} interrupted: {result.reason}", file=sys.stderr)
        return 3
    print(result.verdict, result.mean, result.expanded_uncertainty, result.run_id)
    return 0 if result.verdict == rig.Verdict.PASS else 1


if __name__ == "__main__":
    try:
        if len(sys.argv) > 1:
            sys.exit(main(Path(sys.argv[1])))
        with tempfile.TemporaryDirectory() as tmp:
            sys.exit(main(Path(tmp) / "records.db"))
    except rig.RigError as exc:  # bad input: one line naming the cause
        print(f"own_procedure: {exc}", file=sys.stderr)
        sys.exit(2)

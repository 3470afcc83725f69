"""Certify the sample bat by BBCOR on a simulated lab rig, from Python (docs/api.md).

    python examples/certify_simulated.py [RECORDS.db]

Records go to RECORDS.db if given, else to a database in a temporary directory. Prints the verdict,
the mean, the expanded uncertainty and the run id; exit status 0 on PASS, 1 on FAIL, 3 if the run
was interrupted (resume it with rig.certify(..., resume=RUN_ID)), 2 on bad input.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import rig

SAMPLE_BAT = Path(__file__).resolve().parents[1] / "protocols" / "examples" / "sample-bat.toml"


def main(db: Path) -> int:
    """Certify on the simulated lab rig, recording in `db`; print the outcome."""
    events = 0

    def count(event: object) -> None:  # every event of the run, live, in order
        nonlocal events
        events += 1

    with rig.open_store(db) as store:
        result = rig.certify(
            bat=rig.Bat.load(SAMPLE_BAT),
            procedure="bbcor",
            rig=rig.simulated("lab"),
            store=store,
            on_event=count,
        )
    if not result.finished:
        print(f"run {result.run_id} interrupted: {result.reason}", file=sys.stderr)
        return 3
    print(result.verdict, result.mean, result.expanded_uncertainty, result.run_id)
    print(f"{result.shots} shots, {events} events, records in {db}", file=sys.stderr)
    return 0 if result.verdict == rig.Verdict.PASS else 1


if __name__ == "__main__":
    try:
        if len(sys.argv) > 1:
            sys.exit(main(Path(sys.argv[1])))
        with tempfile.TemporaryDirectory() as tmp:
            sys.exit(main(Path(tmp) / "records.db"))
    except rig.RigError as exc:  # bad input: one line naming the cause
        print(f"certify_simulated: {exc}", file=sys.stderr)
        sys.exit(2)

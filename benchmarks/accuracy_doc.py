"""Regenerate docs/accuracy.md: the work-precision study, its figures and raw data (about 1-2 minutes).

Run from the repository root: .venv/bin/python benchmarks/accuracy_doc.py [--repeats N] [--no-near-rigid]
(--rebuild rewrites the text and figures from docs/accuracy.json without measuring again).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

# Before numba starts OpenMP: with the default (spin) wait policy, parallel calls have been seen to
# cost ~8 ms each while another process is busy, which would swamp the efficiency-curve timings.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks.accuracy_writer


def main() -> int:
    from benchmarks.accuracy_writer import rebuild_accuracy_doc, write_accuracy_doc

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default="docs/accuracy.md", help="the Markdown file to write")
    parser.add_argument("--repeats", type=int, default=5, help="timed repeats per solve (best of N)")
    parser.add_argument("--no-near-rigid", action="store_true", help="skip the slow 1 MHz stiffness probe")
    parser.add_argument("--no-probe", action="store_true", help="skip the parallel-call (OpenMP) probe")
    parser.add_argument(
        "--rebuild",
        action="store_true",
        help="rewrite text and figures from the saved JSON, measuring nothing",
    )
    args = parser.parse_args()
    if args.rebuild:
        done = rebuild_accuracy_doc(Path(args.out))
    else:
        done = write_accuracy_doc(
            Path(args.out), repeats=args.repeats, near_rigid=not args.no_near_rigid, probe=not args.no_probe
        )
    for path in [done["doc"], done["data"], *done["figures"]]:
        print(f"wrote {path}", file=sys.stderr)
    verb = "the measuring run took" if args.rebuild else "took"
    print(f"{verb} {done['elapsed_s']:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

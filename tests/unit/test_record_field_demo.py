"""What a new record field takes: a shot's outcome gains `n_crossings` (the gate events the shot's
raw record holds), recorded, read back typed and shown in the report's shots.

The change is the `EDITS` below, applied to a copy of the package: two files, the typed record
that declares the field (rig/core/outcomes.py, marked shown) and the evaluation that fills it
(protocols/evaluate.py). Nothing else changes: the event's payload translation, the fold, the
report's shots and the JSON export of a run take it from the declaration. A BBCOR run is then
certified with the copy; its log, fold and report carry the field, and a record written before it
existed (tests/fixtures/log-8802354.db) still reports byte for byte. Exporting it as a column of the
`shots` view would be a third file (rig/store/_views.py, the view's columns).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIXTURES = ROOT / "tests" / "fixtures"

# (file, text before, text after): the whole change
EDITS = (
    (
        "rig/core/outcomes.py",
        "    dry_run: bool | None = None  # a rehearsal's nominal shot: nothing was fired\n",
        "    dry_run: bool | None = None  # a rehearsal's nominal shot: nothing was fired\n"
        "    n_crossings: int | None = field(default=None, metadata=SHOWN)  # gate events recorded\n",
    ),
    (
        "protocols/evaluate.py",
        '    out: dict[str, Any] = {"metric_name": p.standard, "metric": None, "u": None}\n',
        '    out: dict[str, Any] = {"metric_name": p.standard, "metric": None, "u": None}\n'
        '    out["n_crossings"] = len(record.crossings)\n',
    ),
)

PROBE = """
import json, sys
from pathlib import Path
from rig.cli import main
from rig.certification import history
from rig.core.run_state import fold
from rig.store import Store

db, bat, out = sys.argv[1], sys.argv[2], sys.argv[3]
code = main(["certify", "--procedure", "bbcor", "--bat", bat, "--sim", "ideal", "--db", db])
assert code in (0, 1), code
with Store.open(db) as store:
    run_id = store.runs()[-1].run_id
    payloads = [e.payload for e in store.entries(run_id) if e.kind in ("ShotMeasured", "ShotRejected")]
    state = fold(history(store, run_id))
    typed = [s.outcome.n_crossings for s in state.shots if s.outcome is not None]
    raw = [len(s.raw.crossings or []) for s in state.shots if s.outcome is not None]
Path(out).write_text(json.dumps({"run_id": run_id, "payloads": [p.get("n_crossings") for p in payloads],
                                 "typed": typed, "raw": raw}))
"""


def _copy(tmp_path: Path) -> Path:
    """The package as installed (rig with its linked folders, as real folders), the edits applied."""
    copy = tmp_path / "src"
    shutil.copytree(ROOT / "rig", copy / "rig", symlinks=False)  # numba's cache comes along
    for name, before, after in EDITS:
        path = copy / "rig" / name.removeprefix("rig/")
        text = path.read_text(encoding="utf-8")
        assert text.count(before) == 1, f"{name}: the edit's anchor is not there once"
        path.write_text(text.replace(before, after), encoding="utf-8")
    return copy


CLI = "import sys; from rig.cli import main; sys.exit(main(sys.argv[1:]))"


def _run(copy: Path, *argv: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PYTHONPATH": str(copy)}
    return subprocess.run(
        [sys.executable, *argv], capture_output=True, text=True, env=env, cwd=copy, timeout=600
    )


@pytest.mark.slow
def test_a_new_shot_field_is_two_files_and_old_records_read_as_before(tmp_path: Path) -> None:
    assert len({name for name, _, _ in EDITS}) == 2  # the number the closing note reports
    copy = _copy(tmp_path)
    db, bat = tmp_path / "r.db", ROOT / "protocols" / "examples" / "sample-bat.toml"
    found = tmp_path / "seen.json"
    done = _run(copy, "-c", PROBE, str(db), str(bat), str(found))
    assert done.returncode == 0, done.stderr
    seen = json.loads(found.read_text())
    # recorded in the log, read back typed, and what the raw record says
    assert seen["payloads"] and seen["payloads"] == seen["typed"] == seen["raw"]
    assert all(n >= 4 for n in seen["typed"])  # inbound and rebound through the gates
    report = _run(copy, "-c", CLI, "report", seen["run_id"], "--format", "json", "--db", str(db))
    assert report.returncode == 0, report.stderr
    shots = [s for s in json.loads(report.stdout)["shots"] if "valid" in s]
    assert shots and all(s["n_crossings"] >= 4 for s in shots)  # shown with no edit of the report
    # a record from before the field: the report is what that code printed
    old = tmp_path / "old.db"
    shutil.copyfile(FIXTURES / "log-8802354.db", old)
    run_id = json.loads((FIXTURES / "log-8802354.runs.json").read_text())["besr"]
    figures = tmp_path / "figures"
    before = _run(
        copy, "-c", CLI, "report", run_id, "--format", "json", "--db", str(old), "--figures", str(figures)
    )
    assert before.returncode == 0, before.stderr
    golden = (FIXTURES / "log-8802354.besr.json").read_text()
    assert before.stdout.replace(str(figures), "FIGURES") == golden

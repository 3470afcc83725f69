"""Benchmark: a BBCOR certification through the three real-instrument twins (SCPI counter, Modbus
PLC, VXM stage with its swing sensor, each on a TCP port) against the same bat on today's sim://
line devices, measured side by side in one run.

Prints each path's wall time per certification (median of --repeat), the ratio, and how far the
twins' certified value lies from the line devices' in units of U (a difference of the noise each
draws, not a bias: both must be within U). Run with `make bench`.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from rig.certification import certify
from rig.core.bat import BatSpec
from rig.core.config import RigConfig
from rig.protocols.procedure import Procedure
from rig.session import scene_with_bat, sim_config
from rig.simulators.instruments.serve import rig_config, start_twins
from rig.simulators.scene import Scene
from rig.simulators.world import SimWorld
from rig.store import Store

BAT = Path(__file__).resolve().parents[1] / "protocols" / "examples" / "sample-bat.toml"


def _certify(db: Path, config: RigConfig) -> tuple[float, dict[str, Any]]:
    bat = BatSpec.load(BAT)
    t0 = time.perf_counter()
    with Store.open(db) as store:
        out = certify(store, Procedure.load("bbcor"), bat, config)
    assert out.status == "finished" and out.verdict is not None, out.reason
    return time.perf_counter() - t0, out.verdict.to_payload()


def through_twins(db: Path, scene: str) -> tuple[float, dict[str, Any]]:
    """One certification through the three instrument twins on one world of `scene`."""
    world = SimWorld(scene_with_bat(Scene.load(scene), BatSpec.load(BAT)))
    twins = start_twins(world)
    try:
        return _certify(db, RigConfig.from_dict(rig_config(world.scene, twins)))
    finally:
        for twin in twins:
            twin.close()


def _shown(seconds: float, v: dict[str, Any]) -> str:
    return f"{seconds:6.2f} s {v['verdict']} {v['mean']:.4f} ± {v['U']:.4f}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--scene", default="lab")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    bat = BatSpec.load(BAT)
    line_s, twin_s, gaps = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        through_twins(Path(tmp) / "warm.db", args.scene)  # numba's cache and the imports, once
        for i in range(args.repeat):
            t_line, v_line = _certify(
                Path(tmp) / f"line{i}.db", sim_config(args.scene, bat=bat, session=f"b{i}")
            )
            t_twin, v_twin = through_twins(Path(tmp) / f"twin{i}.db", args.scene)
            line_s.append(t_line)
            twin_s.append(t_twin)
            gaps.append((v_twin["mean"] - v_line["mean"]) / max(v_twin["U"], v_line["U"]))
            print(f"run {i + 1}: sim:// {_shown(t_line, v_line)}; twins {_shown(t_twin, v_twin)}")
    a, b = statistics.median(line_s), statistics.median(twin_s)
    print(f"median wall time per certification: sim:// {a:.2f} s, twins {b:.2f} s (ratio {b / a:.2f})")
    print(f"twins minus sim:// in units of U: {', '.join(f'{g:+.2f}' for g in gaps)} (|gap| <= 1 expected)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

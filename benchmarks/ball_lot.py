"""A qualified ball lot on a simulated lab: registered, then tested by ball-cor through the real drivers."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from protocols.ball_procedure import BallProcedure
from protocols.ball_terms import terms_from_lot
from rig.balls import run_ball_test
from rig.core.ball import BallLot, Conditioning
from rig.session import sim_config
from rig.store import Store


def measured_terms(scene: str, lot_id: str = "SIM-LOT") -> dict[str, Any]:
    """The ball terms of a lot measured by `ball-cor` on `scene` (its own store, thrown away)."""
    procedure = BallProcedure.load("ball-cor")
    lot = BallLot(
        id=lot_id,
        maker="simulated",
        model="lab ball",
        conditioning=Conditioning(temperature_c=21.0, humidity_pct=50.0),
    )
    config = sim_config(scene, target=(procedure.target.kind, procedure.target.diameter_m))
    with tempfile.TemporaryDirectory() as folder, Store.open(Path(folder) / "lot.db") as store:
        store.register_lot(lot)
        run_ball_test(store, procedure, lot, config)
        lot_now, results = store.ball_lot(lot_id)
        return terms_from_lot(lot_now, results).model_dump(mode="json")

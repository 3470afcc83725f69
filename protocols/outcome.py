"""What every shot evaluation shares: the record of a shot without data, the aim it teaches, its validity."""

from __future__ import annotations

from typing import Any

from rig.measure.validity import Invalidity, is_valid


def no_data(out: dict[str, Any], exc: Exception, **after: Any) -> dict[str, Any]:
    """The outcome of a shot whose beam breaks gave no speeds: invalid, naming why."""
    return {
        **out,
        "valid": False,
        "reasons": [{"code": "NO_DATA", "message": str(exc), "invalidates": True}],
        **after,
    }


def learned_aim(aim_factor: float, target_speed: float, at_impact: float) -> float:
    """The aim factor after a shot: the cannon gave `at_impact` where the aim table promised the aimed
    speed (target / factor); half the old factor, half the ratio."""
    aimed = target_speed / aim_factor
    return 0.5 * aim_factor + 0.5 * (at_impact / aimed)


def concluded(out: dict[str, Any], reasons: list[Invalidity], failure: str) -> dict[str, Any]:
    """`out` with its validity reasons (and the device's failure, if any) and whether it is valid."""
    out["reasons"] = [
        {
            "code": r.code.value,
            "message": r.message,
            "invalidates": r.invalidates,
            "measured": r.measured,
            "limit": r.limit,
        }
        for r in reasons
    ]
    if failure:
        out["reasons"].append({"code": "SHOT_FAILED", "message": failure, "invalidates": True})
    out["valid"] = is_valid(reasons) and not failure and out["metric"] is not None
    return out

"""What every shot evaluation shares: the record of a shot without data, the aim it teaches, its validity."""

from __future__ import annotations

from typing import Any

from rig.core.outcomes import ShotOutcome
from rig.measure.validity import Invalidity, is_valid


def no_data(out: dict[str, Any], exc: Exception, **after: Any) -> ShotOutcome:
    """The outcome of a shot whose beam breaks gave no speeds: invalid, naming why."""
    return ShotOutcome(
        **{
            **out,
            "valid": False,
            "reasons": [{"code": "NO_DATA", "message": str(exc), "invalidates": True}],
            **after,
        }
    )


AIM_GAIN_MIN = 0.2  # the aim keeps following a drifting cannon, averaging about 9 shots' scatter


def learned_aim(aim_factor: float, target_speed: float, at_impact: float, taught: int = 0) -> float:
    """The aim factor after a shot: the cannon gave `at_impact` where the aim table promised the aimed
    speed (target / factor); `taught` shots taught the aim before this one.

    The factor is the running mean of the shots' ratios (gain 1/(taught + 1)), then an exponential
    mean of gain AIM_GAIN_MIN: a fixed gain of 1/2 made the aim chase each shot's own scatter,
    which widened the speeds' spread by about 15 % and sent more shots outside the speed window.
    """
    aimed = target_speed / aim_factor
    gain = max(1.0 / (taught + 1), AIM_GAIN_MIN)
    return (1.0 - gain) * aim_factor + gain * (at_impact / aimed)


def concluded(out: dict[str, Any], reasons: list[Invalidity], failure: str) -> ShotOutcome:
    """The outcome: `out`, the fields evaluated so far, with its validity reasons (and the device's
    failure, if any) and whether it is valid. A field ShotOutcome does not have is a TypeError here."""
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
    return ShotOutcome(**out)

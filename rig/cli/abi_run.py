"""Who reports an accelerated break-in's rollings in `rig certify`, and the simulated bench it rolls.

A simulated run (--sim) is scripted: the rollings the plan asks for are reported by the script and
the simulated barrel rolled so (a resumed run's new world is first rolled as its record says). On a
real rig at a terminal a person reports them (rig.cli.rolling); without a terminal, a script does.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import Any

from rig.core import events as ev
from rig.core.config import RigConfig
from rig.protocols.control import Operator, RunControl, ScriptedOperator

SCRIPT_WHO = "script (--sim or scripted run)"
RigFor = Callable[[RigConfig], RigConfig]


def _same(config: RigConfig) -> RigConfig:
    return config


def recorded_rollings(store: Any, run_id: str | None) -> list[tuple[float, int]]:
    """The rollings (depth in, passes) run `run_id` has recorded, in order ([] for a new run)."""
    if run_id is None:
        return []
    entries = store.entries(run_id, kinds=[ev.BARREL_ROLLED])
    return [(float(e.payload["depth_in"]), int(e.payload["passes"])) for e in entries]


@contextlib.contextmanager
def run_operator(
    args: argparse.Namespace, store: Any, run_id: str | None, is_abi: bool, control: RunControl
) -> Iterator[tuple[Operator, RigFor]]:
    """The run's operator and what its rig config becomes (a simulated ABI: the tester's twin added);
    a prompt waiting at the terminal gives way to a stop of `control` (Ctrl-C, SIGTERM)."""
    from rig.cli.rolling import ScriptedRoller, TerminalRoller, parse_who, terminal_reader

    rolled_by = None if args.rolled_by is None else _checked_name(args.rolled_by, parse_who)
    if not is_abi:
        if rolled_by is not None:
            from rig.core.errors import ConfigError

            raise ConfigError(
                "--rolled-by goes with an accelerated break-in (--procedure abi)", "--rolled-by"
            )
        yield ScriptedOperator(who=SCRIPT_WHO), _same
        return
    if args.sim is not None:
        from rig.sim_break_in import SimBreakIn

        bench = SimBreakIn(recorded_rollings(store, run_id))
        try:
            yield ScriptedRoller(who=SCRIPT_WHO, rolled_by=rolled_by, hands=bench.roll), bench.attach
        finally:
            bench.close()
        return
    if sys.stdin.isatty():
        stopped = terminal_reader(lambda: control.reason if control.aborted else None)
        yield TerminalRoller(rolled_by=rolled_by, read=stopped), _same
        return
    yield ScriptedRoller(who=SCRIPT_WHO, rolled_by=rolled_by), _same


def _checked_name(name: str, parse: Callable[[str], str]) -> str:
    from rig.core.errors import ConfigError

    try:
        return parse(name)
    except ValueError as exc:
        raise ConfigError(str(exc), source="--rolled-by") from None

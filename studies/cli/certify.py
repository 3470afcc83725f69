"""`rig-study population --certify N`: certify a simulated population of bats into a record store.

Each bat is certified in-process through the real drivers on its own simulated rig (as `rig
certify --sim` does), its bat file written next to the store (STORE-bats/). One stop signal
finishes the shot in progress, records the run as interrupted and ends the loop; running the same
command again resumes that run and certifies the bats still missing, never one twice.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rig.cli.common import ConfigError, open_db
from rig.cli.common import console as terminal
from rig.core.events import Verdict
from rig.core.files import CONFIG_BYTES, read_json_file, read_text
from studies.population.simulated import SimulatedBat, simulated_population

MAX_BATS = 500
MAX_ALTERATION = 0.2


@dataclass
class Tally:
    """What the population run did."""

    certified: list[dict[str, Any]] = field(default_factory=list)
    skipped: int = 0
    seconds: list[float] = field(default_factory=list)
    stopped: str = ""

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        return {
            "certified": self.certified,
            "already_done": self.skipped,
            "seconds_per_certification": self.seconds,
            "stopped": self.stopped or None,
        }


def bats_dir(db: str) -> Path:
    """Where the bat files go: beside the store, STORE-bats/."""
    path = Path(db)
    return path.with_name(f"{path.stem}-bats")


def check_args(args: argparse.Namespace) -> None:
    """One clear line for each flag out of range (exit 2)."""
    if args.certify is None:
        if args.altered or args.seed:
            raise ConfigError("--altered and --seed go with --certify N", source="command line")
        return
    if not args.db:
        raise ConfigError("--certify needs --db STORE: the runs go into that store", source="command line")
    if args.data:
        raise ConfigError("--certify makes its own bats: leave out --data", source="command line")
    if not 1 <= args.certify <= MAX_BATS:
        raise ConfigError(f"--certify {args.certify}: give 1-{MAX_BATS} bats", source="command line")
    if not 0 <= args.altered <= args.certify:
        raise ConfigError(f"--altered {args.altered}: give 0-{args.certify} bats", source="command line")
    if not 0.0 < args.alteration <= MAX_ALTERATION:
        raise ConfigError(
            f"--alteration {args.alteration:g}: give a BBCOR above 0, at most {MAX_ALTERATION:g}",
            source="command line",
        )
    if not 0 <= args.seed < 2**32:
        raise ConfigError(f"--seed {args.seed}: give 0 to {2**32 - 1}", source="command line")


def _plan(args: argparse.Namespace) -> dict[str, Any]:
    return {
        "kind": "rig-simulated-population",
        "n": args.certify,
        "seed": args.seed,
        "altered": args.altered,
        "alteration_bbcor": args.alteration,
        "scene": args.scene,
        "procedure": args.procedure,
    }


def write_bat_files(args: argparse.Namespace, bats: list[SimulatedBat]) -> Path:
    """The bat files and population.json in STORE-bats/; refuses a folder of another population."""
    folder = bats_dir(args.db)
    folder.mkdir(parents=True, exist_ok=True)
    plan_file = folder / "population.json"
    plan = _plan(args)
    if plan_file.exists():
        before = read_json_file(plan_file, CONFIG_BYTES, "a population plan")[0]
        if not isinstance(before, dict):
            raise ConfigError("not a population plan: not a JSON object", source=str(plan_file))
        if before != plan:
            differs = ", ".join(k for k in plan if before.get(k) != plan[k])
            raise ConfigError(
                f"this store's simulated population was made with other flags ({differs}):"
                " repeat them to continue, or give another --db",
                source=str(plan_file),
            )
    else:
        plan_file.write_text(json.dumps(plan, indent=2) + "\n", encoding="utf-8")
    for bat in bats:
        path = folder / f"{bat.spec.id}.toml"
        text = bat.toml(args.scene, args.seed)
        if path.exists() and read_text(path, CONFIG_BYTES, "a bat file") != text:
            raise ConfigError("the bat file was changed; restore or remove it", source=str(path))
        path.write_text(text, encoding="utf-8")
    return folder


def _sim_config(scene_name: str, bat: SimulatedBat) -> tuple[Any, str]:
    """A rig config on a fresh simulated rig whose bat is this one (true MOI, alteration)."""
    from rig.session import scene_with_bat, sim_config
    from rig.simulators.scene import Scene
    from rig.simulators.urlhandler import install_world

    rig = f"population-{uuid.uuid4().hex[:8]}"
    true_bat = bat.spec.model_copy(update={"moi_kgm2": bat.moi_kgm2})  # the file leaves it to the rig
    scene = scene_with_bat(Scene.load(scene_name), true_bat)
    if bat.altered:
        scene = scene.with_alteration(bat.alteration_bbcor)
    config = sim_config(scene_name, rig_name=rig)  # no bat: the world is installed here instead
    install_world(rig, scene_name, scene)
    return config, rig


def _state(store: Any, bat_id: str) -> tuple[str, str | None]:
    """('done' | 'resume' | 'new', run id) of the bat's runs in the store."""
    runs = [r for r in store.runs() if r.bat_id == bat_id]
    if any(r.status == "finished" for r in runs):
        return "done", None
    open_runs = [r for r in runs if r.status == "running"]
    return ("resume", open_runs[-1].run_id) if open_runs else ("new", None)


def certify_population(args: argparse.Namespace) -> Tally:
    """Certify the population's bats still missing from the store; stops on the first signal."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from rig.certification import certify
    from rig.core import events as ev
    from rig.protocols.control import RunControl, ScriptedOperator
    from rig.protocols.procedure import Procedure
    from rig.run_signals import stop_on_signals
    from rig.simulators.scene import Scene
    from rig.simulators.urlhandler import drop_world

    check_args(args)
    scene = Scene.load(args.scene)  # a bad scene is refused before anything is written
    if args.altered:
        scene.with_alteration(args.alteration)  # ... and one that cannot alter a bat
    procedure = Procedure.load(args.procedure)
    bats = simulated_population(args.certify, args.seed, args.altered, args.alteration)
    folder = write_bat_files(args, bats)
    tally, control = Tally(), RunControl()
    console = terminal(stderr=True)
    console.print(f"rig-study: {len(bats)} simulated bats (scene {args.scene}); bat files in {folder}")
    args.create_db = True
    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("{task.fields[last]}"),
    )
    shown = Progress(*columns, console=console, disable=not console.is_terminal)  # a bar only on a terminal
    # the study of the store may follow: a signal then is the user's, not a late one for a run
    analysis_follows = bool(args.json or args.plot_dir or args.calibration)
    with stop_on_signals(control, until_exit=not analysis_follows), open_db(args) as store, shown as bar:
        task = bar.add_task("certifying", total=len(bats), last="")
        for bat in bats:
            control.settled = False  # the last bat's run is recorded: a signal from here stops the study
            state, run_id = _state(store, bat.spec.id)
            if state == "done":
                tally.skipped += 1
                bar.advance(task)
                continue
            if control.aborted:  # a signal between two bats: nothing of this one is recorded yet
                tally.stopped = f"{control.reason} before bat {bat.spec.id}"
                break
            shots = [0]

            def on_event(event: Any, bat: SimulatedBat = bat, shots: list[int] = shots) -> None:
                if event.kind == ev.SHOT_MEASURED:
                    shots[0] += 1
                    bar.update(task, description=f"{bat.spec.id} {bat.spec.hoop_hz:.0f} Hz shot {shots[0]}")

            bar.update(task, description=f"{bat.spec.id} {bat.spec.hoop_hz:.0f} Hz")
            config, rig = _sim_config(args.scene, bat)
            started = time.perf_counter()
            try:
                outcome = certify(
                    store,
                    procedure,
                    bat.spec,
                    config,
                    run_id=run_id,
                    operator=ScriptedOperator(who="script (rig-study population --certify)"),
                    subscribers=[on_event],
                    control=control,
                )
            finally:
                drop_world(rig)
            seconds = time.perf_counter() - started
            if outcome.status != "finished":
                tally.stopped = f"bat {bat.spec.id}: run {outcome.run_id} {outcome.status}: {outcome.reason}"
                break
            verdict = outcome.verdict
            tally.seconds.append(seconds)
            tally.certified.append(
                {
                    "bat_id": bat.spec.id,
                    "hoop_hz": bat.spec.hoop_hz,
                    "altered": bat.altered,
                    "verdict": verdict and verdict.verdict,
                    "metric": verdict and verdict.metric,
                    "value": verdict and verdict.mean,
                    "location_in": verdict and verdict.location_in,
                    "seconds": seconds,
                    "resumed": state == "resume",
                }
            )
            mean = verdict and verdict.mean
            last = f"{bat.spec.id}: {verdict and verdict.verdict} {mean:.4f}" if mean is not None else ""
            bar.update(task, advance=1, last=last)
    return tally


def print_summary(tally: Tally, args: argparse.Namespace) -> None:
    """What was certified, how long it took, and what is left."""
    console = terminal(stderr=True)
    done = tally.certified
    console.print(
        f"certified {len(done)} bat(s) into {args.db}; {tally.skipped} already there"
        + (f"; stopped: {tally.stopped}" if tally.stopped else "")
    )
    legal, altered = [r for r in done if not r["altered"]], [r for r in done if r["altered"]]
    groups = (("legal", legal), ("altered", altered))
    for label, rows in groups:
        values = [r["value"] for r in rows if r["value"] is not None]
        if values:
            fails = sum(1 for r in rows if r["verdict"] != Verdict.PASS)
            metric = str(rows[0]["metric"] or "metric").upper()
            console.print(
                f"  {label}: {len(values)} bats, {metric} {min(values):.4f}-{max(values):.4f}"
                f" (mean {statistics.fmean(values):.4f}), {fails} not PASS"
            )
    if tally.seconds:
        console.print(
            f"  time per certification: median {statistics.median(tally.seconds):.2f} s,"
            f" max {max(tally.seconds):.2f} s"
        )
    if tally.stopped:
        console.print("  run the same command again to resume and certify the rest")


def run(args: argparse.Namespace) -> int:
    """Certify, summarise; 3 if stopped before every bat was certified (resumable)."""
    tally = certify_population(args)
    print_summary(tally, args)
    if args.json and tally.stopped:
        json.dump(tally.as_dict(), sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    return 3 if tally.stopped else 0

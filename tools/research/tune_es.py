"""Tune NLVG-PID (or fixed-PID) gains by extremum seeking from a config (SPEC §6.3, paper section 3.2).

Usage::

    python -m tools.research.tune_es --config tools/research/experiments/attitude_nlvg.yaml --out runs/tune_attitude
        [--vehicle delivery650] [--iterations N] [--restarts R] [--seed S] [--quiet]
    python -m tools.research.tune_es --ship --vehicle x500 [--iterations N] [--restarts R] [--workers W]
        [--ship-structure nlvg|pid|none] [--out DIR]
    python -m tools.research.tune_es --ship-noise-model [--vehicle delivery650] [--effort-scale S]

``--config``: writes into ``--out``: ``gains.yaml`` (a gains file: ``CascadeGains.from_yaml`` and the
autopilot's ``--params`` take it as it is), ``j_per_iteration.csv``, ``convergence.png``, ``k_of_s.png`` (the
tuned k_p, k_i, k_d per channel against |e|) and ``summary.json``.
``--vehicle`` (default delivery650, the airframe ``make run`` flies) replaces the config's ``vehicle``.

``--ship``: an airframe's default gains, tuned on its own closed loop (issue 22): the simulator's sensor models
-> the EKF -> the autopilot's commander, navigator and cascade, in process and seeded, on short delivery legs
in wind with the parcel and the paper's small steps; cost on the TRUE tracking error plus motor chatter
(:mod:`tools.research.experiments.loop_tuner`), rollouts on the campaign engine (``--workers``). The fixed PID and the
NLVG-PID are tuned with the same cost and budget; both land in ``--out`` (default
``results/loop_tuning/<vehicle>``: ``pid.yaml``, ``nlvg.yaml``, ``summary.json``) and ``--ship-structure``
is copied to ``autopilot/control/airframe_gains/<vehicle>.yaml``, the airframe's parameter defaults.
Exit status 0 on success, 1 if tuning failed, 2 on a bad config.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from autopilot.control.param_decls import DEFAULT_GAINS_PATH
from autopilot.tuning import EsError, EsIteration
from tools.research.experiments.tune_config import TuneConfigError, load_tune_config
from tools.research.experiments.tuner import provenance, tune, write_outputs

DEFAULT_VEHICLE = "delivery650"
#: ES budget of ``--ship`` (the NLVG's; the fixed PID gets at least as many rollouts)
SHIP_ITERATIONS = 3
SHIP_RESTARTS = 1


def ship(args: argparse.Namespace, argv: list[str] | None, console: Console) -> int:
    """``--ship``: both structures tuned on ``--vehicle``'s own closed loop, the chosen one to its defaults."""
    from tools.research.experiments.loop_ship import ship_loop, ship_paper_pid

    command = "python -m tools.research.tune_es " + " ".join(sys.argv[1:] if argv is None else argv)
    if args.ship_structure == "paper":
        target = ship_paper_pid(args.vehicle, command, args.candidates_from)
        console.print(f"the paper's fixed PID is the default of {args.vehicle}: {target}")
        return 0
    try:
        paths = ship_loop(
            args.vehicle,
            iterations=SHIP_ITERATIONS if args.iterations is None else args.iterations,
            restarts=SHIP_RESTARTS if args.restarts is None else args.restarts,
            workers=args.workers,
            ship=args.ship_structure,
            out_dir=Path(args.out) if args.out else None,
            command=command,
            log=lambda msg: console.print(msg),
        )
    except (EsError, ValueError, RuntimeError) as exc:
        console.print(f"[red]ship failed:[/red] {exc}")
        return 1
    console.print(f"tuned gains for {args.vehicle}: {paths['pid']}, {paths['nlvg']}")
    return 0


def ship_noise_model(vehicle: str, iterations: int | None, effort_scale: float, console: Console) -> int:
    """``--ship-noise-model``: the generic default gains of issue 14 (:data:`DEFAULT_GAINS_PATH`), tuned in the
    batched rollouts with the estimated feedback-noise model (:mod:`tools.research.experiments.noisy_pipeline`); they
    fly airframes without their own tuned file. Written as ``--ship --vehicle V --effort-scale S`` before
    issue 22."""
    from tools.research.experiments.noisy_pipeline import tune_noisy_pair

    try:
        pair = tune_noisy_pair(vehicle, effort_scale, iterations, log=lambda msg: console.print(msg))
    except (EsError, TuneConfigError, ValueError) as exc:
        console.print(f"[red]ship failed:[/red] {exc}")
        return 1
    command = (
        f"python -m tools.research.tune_es --ship-noise-model --vehicle {vehicle} --effort-scale {effort_scale:g}"
        + (f" --iterations {iterations}" if iterations is not None else "")
    )
    levels = {}
    for level in ("attitude", "position"):
        o = pair.outcomes[(level, "nlvg")]
        levels[level] = provenance(o.config, command, o, j_warm_start_pid=pair.j_warm_start[level])
    out = DEFAULT_GAINS_PATH
    pair.gains["nlvg"].to_yaml(out, provenance={"command": command, "vehicle": vehicle, "levels": levels})
    console.print(f"generic NLVG-PID gains (noise model, {vehicle}): {out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.research.tune_es", description=__doc__.splitlines()[0])
    parser.add_argument("--config", help="tuning config YAML (tools/research/experiments/*.yaml)")
    parser.add_argument("--ship", action="store_true", help="tune the shipped default gains (see the docstring)")
    parser.add_argument("--vehicle", default=DEFAULT_VEHICLE, help="airframe to tune (default %(default)s)")
    parser.add_argument("--out", help="output directory (--config) or gains file (--ship)")
    parser.add_argument("--iterations", type=int, default=None, help="override es.iterations")
    parser.add_argument(
        "--ship-noise-model", action="store_true", help="the generic default gains of the feedback-noise model"
    )
    parser.add_argument("--effort-scale", type=float, default=1.0, help="--ship-noise-model: multiplies the configs' λ")
    parser.add_argument("--workers", type=int, default=2, help="--ship: rollout worker processes (0: in process)")
    parser.add_argument(
        "--ship-structure",
        choices=("nlvg", "pid", "none", "paper"),
        default="nlvg",
        help="--ship: which tuned structure becomes the airframe's defaults (default %(default)s); paper: no "
        "tuning, the paper's fixed PID",
    )
    parser.add_argument(
        "--candidates-from", default=None, help="--ship-structure paper: the airframe whose tuned sets were compared"
    )
    parser.add_argument("--restarts", type=int, default=None, help="override es.restarts")
    parser.add_argument("--seed", type=int, default=None, help="override es.seed")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    console = Console(stderr=True)
    if args.ship:
        return ship(args, argv, console)
    if args.ship_noise_model:
        return ship_noise_model(args.vehicle, args.iterations, args.effort_scale, console)
    if not (args.config and args.out):
        parser.error("--config and --out are required (or --ship)")
    try:
        config = load_tune_config(args.config).with_budget(args.iterations, args.restarts)
        config = replace(config, vehicle=args.vehicle)
        if args.seed is not None:
            config = replace(config, es=replace(config.es, seed=args.seed))
    except (TuneConfigError, ValueError) as exc:
        console.print(f"[red]config error:[/red] {exc}")
        return 2

    total = config.es.iterations + 1
    with Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("J_best {task.fields[j_best]:.6g}"),
        TimeElapsedColumn(),
        console=console,
        disable=args.quiet,
    ) as progress:
        task = progress.add_task(f"ES {config.name}", total=total, j_best=float("inf"))

        def on_iteration(it: EsIteration) -> None:
            progress.update(task, completed=it.iteration + 1, j_best=it.j_best)

        try:
            outcome = tune(config, on_iteration)
        except EsError as exc:
            console.print(f"[red]ES failed:[/red] {exc}")
            return 1
    paths = write_outputs(
        outcome,
        args.out,
        command="python -m tools.research.tune_es " + " ".join(sys.argv[1:] if argv is None else argv),
    )
    res = outcome.result
    console.print(
        f"{config.name}: J {res.j_initial:.6g} -> {res.j_best:.6g} ({res.n_evaluations} rollouts in "
        f"{res.n_batches} batches, {outcome.wall_s:.1f} s); gains: {paths['gains']}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

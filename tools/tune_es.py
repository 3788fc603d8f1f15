"""Tune NLVG-PID (or fixed-PID) gains by extremum seeking from a config (SPEC §6.3, paper section 3.2).

Usage::

    python -m tools.tune_es --config tools/experiments/attitude_nlvg.yaml --out runs/tune_attitude
        [--vehicle delivery650] [--iterations N] [--restarts R] [--seed S] [--quiet]
    python -m tools.tune_es --ship [--vehicle delivery650] [--out autopilot/control/default_gains.yaml]

``--config``: writes into ``--out``: ``gains.yaml`` (a gains file: ``CascadeGains.from_yaml`` and the
autopilot's ``--params`` take it as it is), ``j_per_iteration.csv``, ``convergence.png``, ``k_of_s.png`` (the
tuned k_p, k_i, k_d per channel against |e|) and ``summary.json``.
``--vehicle`` (default delivery650, the airframe ``make run`` flies) replaces the config's ``vehicle``.

``--ship``: the shipped default gains. Tunes the whole cascade in the noisy, effort-aware setting
(``attitude_noisy.yaml`` then ``position_noisy.yaml``: a fixed PID first, then the NLVG-PID warm-started at
it, :mod:`tools.experiments.noisy_pipeline`) on ``--vehicle`` and writes the NLVG gains, with the command and
seeds that produced them, to ``--out`` (default ``autopilot/control/default_gains.yaml``, where the
``NV_*`` parameter defaults come from). Exit status 0 on success, 1 if ES failed, 2 on a bad config.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from autopilot.control.param_decls import DEFAULT_GAINS_PATH
from autopilot.tuning import EsError, EsIteration
from tools.experiments.tune_config import TuneConfigError, load_tune_config
from tools.experiments.tuner import provenance, tune, write_outputs

DEFAULT_VEHICLE = "delivery650"
#: λ multiplier of the shipped gains (the configs' λ as they are; the λ sweep of make paper shows the trade-off)
SHIP_EFFORT_SCALE = 1.0


def ship(
    vehicle: str,
    out: str,
    iterations: int | None = None,
    effort_scale: float = 1.0,
    console: Console | None = None,
) -> int:
    """Tune the noisy effort-aware cascade on ``vehicle`` and write its NLVG gains to ``out`` (see the docstring)."""
    from tools.experiments.noisy_pipeline import tune_noisy_pair

    console = console or Console(stderr=True)
    try:
        pair = tune_noisy_pair(vehicle, effort_scale, iterations, log=lambda msg: console.print(msg))
    except (EsError, TuneConfigError, ValueError) as exc:
        console.print(f"[red]ship failed:[/red] {exc}")
        return 1
    command = f"python -m tools.tune_es --ship --vehicle {vehicle} --effort-scale {effort_scale:g}" + (
        f" --iterations {iterations}" if iterations is not None else ""
    )
    levels = {}
    for level in ("attitude", "position"):
        o = pair.outcomes[(level, "nlvg")]
        levels[level] = provenance(o.config, command, o, j_warm_start_pid=pair.j_warm_start[level])
    pair.gains["nlvg"].to_yaml(out, provenance={"command": command, "vehicle": vehicle, "levels": levels})
    console.print(f"shipped NLVG-PID gains for {vehicle}: {out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.tune_es", description=__doc__.splitlines()[0])
    parser.add_argument("--config", help="tuning config YAML (tools/experiments/*.yaml)")
    parser.add_argument("--ship", action="store_true", help="tune the shipped default gains (see the docstring)")
    parser.add_argument("--vehicle", default=DEFAULT_VEHICLE, help="airframe to tune (default %(default)s)")
    parser.add_argument("--out", help="output directory (--config) or gains file (--ship)")
    parser.add_argument("--iterations", type=int, default=None, help="override es.iterations")
    parser.add_argument(
        "--effort-scale",
        type=float,
        default=SHIP_EFFORT_SCALE,
        help="--ship: multiplies the configs' effort weight λ (default %(default)s)",
    )
    parser.add_argument("--restarts", type=int, default=None, help="override es.restarts")
    parser.add_argument("--seed", type=int, default=None, help="override es.seed")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    console = Console(stderr=True)
    if args.ship:
        out = args.out or str(DEFAULT_GAINS_PATH)
        return ship(args.vehicle, out, args.iterations, args.effort_scale, console)
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
        outcome, args.out, command="python -m tools.tune_es " + " ".join(sys.argv[1:] if argv is None else argv)
    )
    res = outcome.result
    console.print(
        f"{config.name}: J {res.j_initial:.6g} -> {res.j_best:.6g} ({res.n_evaluations} rollouts in "
        f"{res.n_batches} batches, {outcome.wall_s:.1f} s); gains: {paths['gains']}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Tune NLVG-PID (or fixed-PID) gains by extremum seeking from a config (SPEC §6.3, paper section 3.2).

Usage::

    python -m tools.tune_es --config tools/experiments/attitude_nlvg.yaml --out runs/tune_attitude
        [--iterations N] [--restarts R] [--seed S] [--quiet]

Writes into ``--out``: ``gains.yaml`` (loadable by ``CascadeGains.from_yaml``), ``j_per_iteration.csv``,
``convergence.png`` and ``summary.json``. Exit status 0 on success, 2 on a bad config.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from autopilot.tuning import EsError, EsIteration
from tools.experiments.tune_config import TuneConfigError, load_tune_config
from tools.experiments.tuner import tune, write_outputs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tools.tune_es", description=__doc__.splitlines()[0])
    parser.add_argument("--config", required=True, help="tuning config YAML (tools/experiments/*.yaml)")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--iterations", type=int, default=None, help="override es.iterations")
    parser.add_argument("--restarts", type=int, default=None, help="override es.restarts")
    parser.add_argument("--seed", type=int, default=None, help="override es.seed")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    console = Console(stderr=True)
    try:
        config = load_tune_config(args.config).with_budget(args.iterations, args.restarts)
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
    paths = write_outputs(outcome, args.out)
    res = outcome.result
    console.print(
        f"{config.name}: J {res.j_initial:.6g} -> {res.j_best:.6g} ({res.n_evaluations} rollouts in "
        f"{res.n_batches} batches, {outcome.wall_s:.1f} s); gains: {paths['gains']}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())

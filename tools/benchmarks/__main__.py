"""``make bench``: run every benchmark suite, print one table, write ``bench/results.json``.

Usage: ``python -m tools.benchmarks [--quick] [--only SUITE ...] [--out PATH] [--workers N] [--scheduler ADDR]``.
The Monte Carlo suites (routing, estimator_mc, es_tuning; campaign sizes its own clusters) run their cases on
the campaign engine (:mod:`tools.campaign.engine`): ``--workers N`` sizes its embedded LocalCluster (default: one
per core),
``--scheduler tcp://HOST:PORT`` uses a running Dask cluster; the numbers do not depend on either.
Numbers are measured in one run on one machine; compare ratios, not absolutes.
``--quick`` is a smoke check with noisier numbers: it only prints the table (``--out PATH`` writes them
elsewhere), so the committed ``bench/results.json`` always holds a full run.
"""

from __future__ import annotations

import argparse
import importlib
import inspect
import json
import pkgutil
import platform
import sys
import time
from pathlib import Path

from tools import benchmarks
from tools.benchmarks import BenchResult
from tools.campaign.engine import SchedulerError

#: The committed results of a full run; a ``--quick`` run never writes here.
FULL_RESULTS = Path("bench/results.json")


def _suites() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(benchmarks.__path__) if not m.name.startswith("_"))


def _print_table(rows: list[tuple[str, BenchResult]]) -> None:
    header = f"{'suite':<12} {'key':<40} {'value':>14}  {'target':<12} {'met':<4} note"
    print(header)
    print("-" * len(header))
    for suite, r in rows:
        met = "" if r.met is None else ("yes" if r.met else "NO")
        value = f"{r.value:.6g}" if isinstance(r.value, float) else str(r.value)
        print(f"{suite:<12} {r.key:<40} {value:>14}  {r.target:<12} {met:<4} {r.note}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m tools.benchmarks",
        description="Run the benchmark suites, print one table and write bench/results.json (make bench).",
        epilog="Numbers are measured in one run on one machine: compare ratios, not absolutes.",
    )
    parser.add_argument("--quick", action="store_true", help="shorter runs (smoke check, noisier numbers)")
    parser.add_argument("--only", nargs="*", default=None, help=f"suites to run (default all: {_suites()})")
    parser.add_argument(
        "--out",
        default=None,
        help=f"where to write the flat JSON results (default {FULL_RESULTS}; with --quick, nowhere unless given)",
    )
    parser.add_argument(
        "--merge",
        action="store_true",
        help=f"keep the keys of suites not run now from the --out file (default for --only into {FULL_RESULTS})",
    )
    parser.add_argument(
        "--replace", action="store_true", help="write only this run's keys, even for --only into the default file"
    )
    parser.add_argument(
        "--workers", type=int, default=None, help="Monte Carlo suites: engine worker processes (default: the cores)"
    )
    parser.add_argument(
        "--scheduler", default=None, help="Monte Carlo suites: a running Dask scheduler (tcp://HOST:PORT)"
    )
    args = parser.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        parser.error(f"--workers must be >= 1, got {args.workers}")
    if args.merge and args.replace:
        parser.error("--merge and --replace contradict each other: choose one")
    names = args.only or _suites()
    engine = {"workers": args.workers, "scheduler": args.scheduler}
    rows: list[tuple[str, BenchResult]] = []
    for name in names:
        module = importlib.import_module(f"tools.benchmarks.{name}")
        t0 = time.perf_counter()
        print(f"[bench] {name} ...", file=sys.stderr, flush=True)
        takes_engine = "workers" in inspect.signature(module.run).parameters  # the Monte Carlo suites
        try:
            rows += [(name, r) for r in module.run(quick=args.quick, **(engine if takes_engine else {}))]
        except SchedulerError as exc:
            print(f"tools.benchmarks: {name}: {exc}", file=sys.stderr)
            return 2
        print(f"[bench] {name} done in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
    _print_table(rows)
    if args.out is None and args.quick:
        print(f"\n--quick: results not written (add --out PATH to keep them; {FULL_RESULTS} holds a full run)")
        return 0
    out = Path(args.out) if args.out is not None else FULL_RESULTS
    if args.quick and out.resolve() == FULL_RESULTS.resolve():
        note = f"tools.benchmarks: --quick numbers are not written to {FULL_RESULTS} (a full run's); use another --out"
        print(note, file=sys.stderr)
        return 2
    out.parent.mkdir(parents=True, exist_ok=True)
    # Some suites only, into the committed file: keep the other suites' keys unless told to replace them.
    subset_into_full = set(names) != set(_suites()) and out.resolve() == FULL_RESULTS.resolve()
    merge = out.is_file() and (args.merge or (subset_into_full and not args.replace))
    results: dict[str, object] = json.loads(out.read_text()) if merge else {}
    results.update({r.key: r.value for _, r in rows})
    results["machine"] = f"{platform.machine()} {platform.processor() or ''} python {platform.python_version()}"
    results["quick"] = args.quick
    out.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    print(f"\n{'merged into' if merge else 'wrote'} {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

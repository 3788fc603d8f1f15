"""``quadsitl campaign``: run a campaign file on Dask, or replay one of its cases (SPEC §14, docs/campaigns.md).

::

    quadsitl campaign FILE.yaml --out DIR [--workers N | --scheduler tcp://HOST:PORT] [--resume]
    quadsitl campaign replay DIR CASE [--mode sitl|inproc]
    quadsitl campaign search FILE.yaml --out DIR [--budget N] [--workers N | --scheduler ADDR] [--resume]
    quadsitl campaign estimate FILE.yaml --out DIR [--mc N | --mc-dir DIR] [--workers N | --scheduler ADDR]

Exit status of a run: 0 every case passed, 1 the campaign finished with cases that did not pass, 2 a refused
campaign file or output folder, 130 interrupted (Ctrl-C or SIGTERM; what was done is written, ``--resume``
completes it).
Replay: 0 the truth hash matched the row's, 1 it did not, 2 no such case. Search: 0 no failing case found, 1 one
found, 2 refused. Estimate: 0 done, 2 refused.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path

from mavlink_bridge.contract.about import version_text

EXIT_OK = 0
EXIT_FAILED_CASES = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``quadsitl campaign FILE.yaml ...`` (``replay`` has its own)."""
    p = argparse.ArgumentParser(
        prog="quadsitl campaign",
        description="Fly many seeded variations of a mission on Dask distributed; one results table and a report.",
        epilog="Replay a case: quadsitl campaign replay DIR CASE. Hunt for failures: quadsitl campaign search FILE "
        "--out DIR; their probability: quadsitl campaign estimate FILE --out DIR. Schema and cluster recipes: "
        "docs/campaigns.md",
    )
    p.add_argument("--version", action="version", version=version_text("quadsitl campaign"))
    p.add_argument("campaign", type=Path, help="campaign file (YAML)")
    p.add_argument("--out", type=Path, required=True, help="output folder (results.parquet, summary.json, report.md)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, help="LocalCluster worker processes (default: the cores)")
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT", help="a running Dask scheduler")
    p.add_argument("--resume", action="store_true", help="fly only the cases DIR has no row for yet")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def _replay_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="quadsitl campaign replay",
        description="Re-fly one case of a campaign from its results row, with a Rerun recording; check its truth hash.",
    )
    p.add_argument("--version", action="version", version=version_text("quadsitl campaign replay"))
    p.add_argument("dir", type=Path, help="the campaign's output folder")
    p.add_argument("case", type=int, help="case id")
    p.add_argument("--mode", choices=("sitl", "inproc"), default=None, help="default: the mode the case ran in")
    return p


def _search_parser(kind: str) -> argparse.ArgumentParser:
    what = {
        "search": "Search a campaign's inputs for its lowest margin (CMA-ES or cross-entropy); every flight a row.",
        "estimate": "Failure probability by cross-entropy importance sampling, beside plain Monte Carlo.",
    }[kind]
    p = argparse.ArgumentParser(prog=f"quadsitl campaign {kind}", description=what,
                                epilog="The search: and estimate: keys: docs/campaigns.md")  # fmt: skip
    p.add_argument("--version", action="version", version=version_text(f"quadsitl campaign {kind}"))
    p.add_argument("campaign", type=Path, help="campaign file (YAML) with a search: key")
    p.add_argument("--out", type=Path, required=True, help="output folder (results.parquet, summary.json, report.md)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, help="LocalCluster worker processes (default: the cores)")
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT", help="a running Dask scheduler")
    p.add_argument("--resume", action="store_true", help="re-run from the file's seed, reading back the rows in DIR")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    if kind == "search":
        p.add_argument("--budget", type=int, default=None, help="flights at most (default: the file's cases)")
    else:
        mc = p.add_mutually_exclusive_group()
        mc.add_argument("--mc", type=int, default=0, metavar="N", help="also fly N plain Monte Carlo cases (DIR/mc)")
        mc.add_argument("--mc-dir", type=Path, default=None, help="a plain campaign folder of the same file")
    return p


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else list(argv)
    if args[:1] == ["replay"]:
        return replay(_replay_parser().parse_args(args[1:]))
    if args[:1] in (["search"], ["estimate"]):
        return search(args[0], _search_parser(args[0]).parse_args(args[1:]))
    return run(build_parser().parse_args(args))


def run(args: argparse.Namespace) -> int:
    from tools.campaign.engine import SchedulerError
    from tools.campaign.runner import CampaignDirError, run_campaign
    from tools.campaign.spec import CampaignFileError, load_campaign

    if args.workers is not None and args.workers < 1:
        print("quadsitl campaign: --workers must be >= 1", file=sys.stderr)
        return EXIT_USAGE
    previous = signal.signal(signal.SIGTERM, _interrupt)  # a CI cancel or a kill: stop as cleanly as Ctrl-C
    try:
        spec = load_campaign(args.campaign)
        outcome = run_campaign(
            spec,
            args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            resume=args.resume,
            progress=not args.no_progress,
        )
    except (CampaignFileError, CampaignDirError, SchedulerError) as exc:
        print(f"quadsitl campaign: {exc}", file=sys.stderr)
        return EXIT_USAGE
    finally:
        signal.signal(signal.SIGTERM, previous)
    summary_path = args.out / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    done = summary.get("cases_done", 0)
    print(
        f"campaign {spec.name}: {done}/{spec.cases} cases ({outcome.flown} flown now, {outcome.skipped} already done)"
    )
    if summary:
        low, high = summary["pass_rate_ci95"]
        rate = summary["pass_rate"]
        print(f"pass rate {rate:.1%} [{low:.1%}, {high:.1%}] 95 % exact; status {summary['status_counts']}")
        print(f"results: {args.out / 'results.parquet'}\nreport:  {args.out / 'report.md'}")
    if outcome.interrupted:
        print(f"interrupted: resume with  quadsitl campaign {args.campaign} --out {args.out} --resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK if summary and summary["passed"] == spec.cases else EXIT_FAILED_CASES


def _interrupt(signum: int, _frame: object) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def search(kind: str, args: argparse.Namespace) -> int:
    """``quadsitl campaign search`` / ``estimate``."""
    from tools.campaign.engine import SchedulerError
    from tools.campaign.runner import CampaignDirError
    from tools.campaign.search_run import SearchSetupError, run_estimate, run_search
    from tools.campaign.spec import CampaignFileError, load_campaign

    prog = f"quadsitl campaign {kind}"
    for name in ("workers", "budget", "mc"):
        value = getattr(args, name, None)
        if value is not None and value < (0 if name == "mc" else 1):
            print(f"{prog}: --{name} must be >= {0 if name == 'mc' else 1}", file=sys.stderr)
            return EXIT_USAGE
    previous = signal.signal(signal.SIGTERM, _interrupt)
    common = {"workers": args.workers, "scheduler": args.scheduler, "resume": args.resume,
              "progress": not args.no_progress}  # fmt: skip
    try:
        spec = load_campaign(args.campaign)
        if kind == "search":
            outcome = run_search(spec, args.out, budget=args.budget, **common)
        else:
            outcome = run_estimate(spec, args.out, mc_dir=args.mc_dir, mc_cases=args.mc, **common)
    except (CampaignFileError, CampaignDirError, SchedulerError, SearchSetupError) as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"interrupted: resume with  {prog} {args.campaign} --out {args.out} --resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        signal.signal(signal.SIGTERM, previous)
    summary = json.loads((args.out / "summary.json").read_text())
    print(f"{kind} {spec.name}: {summary['flights']} flights ({outcome.flown} flown now, {outcome.reused} read back)")
    if kind == "search":
        ftf = summary["flights_to_first_failure"]
        print(f"lowest margin {summary['lowest_margin']:.4g} ({summary['margin']}); {summary['failures']} failing "
              f"flights, the first at flight {ftf if ftf is not None else '-'}")  # fmt: skip
        for w in summary["worst"][:3]:
            print(f"  case {w['case_id']}: margin {w['margin']:.4g}  {w['replay']}")
    else:
        low, high = summary["p_is_ci95"]
        print(f"P(failure) {summary['p_is']:.3g} [{low:.3g}, {high:.3g}] 95 %; ESS {summary['ess_kish']:.1f}, "
              f"mean weight {summary['mean_weight']:.3f}")  # fmt: skip
        if summary["mc"]:
            mc = summary["mc"]
            print(f"plain Monte Carlo {mc['p']:.3g} ({mc['failures']}/{mc['flights']}) [{mc['ci95'][0]:.3g}, "
                  f"{mc['ci95'][1]:.3g}]")  # fmt: skip
    print(f"results: {args.out / 'results.parquet'}\nreport:  {args.out / 'report.md'}")
    if kind == "search":
        return EXIT_FAILED_CASES if summary["flights_to_first_failure"] is not None else EXIT_OK
    return EXIT_OK


def replay(args: argparse.Namespace) -> int:
    from tools.campaign.replay import ReplayError, replay_case

    try:
        result = replay_case(args.dir, args.case, mode=args.mode)
    except ReplayError as exc:
        print(f"quadsitl campaign replay: {exc}", file=sys.stderr)
        return EXIT_USAGE
    print(result.text)
    return EXIT_OK if result.matched else EXIT_FAILED_CASES


if __name__ == "__main__":
    sys.exit(main())

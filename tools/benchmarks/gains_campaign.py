"""The shipped gains against the paper's fixed PID where they fly (issue 22 item 1): the delivery mission
(``missions/delivery.yaml``: wind 1.5/−1.0 m/s with 0.5 m/s gusts, the parcel) with the EKF, in process,
seeded, on x500 and delivery650.

Per airframe the same held-out seeds (sensor noise and biases) fly three gain sets: the airframe's shipped
defaults (``shipped``), the paper's fixed PID (``CascadeGains.fixed_pid()``, ``paper_pid``) and the fixed PID
tuned by the same extremum seeking on the same loop with the same budget (``es_pid``,
``results/loop_tuning/<tuned on>/pid.yaml``, the airframe the shipped set was tuned on). Each flight is
:func:`tools.research.experiments.loop_rollout.fly_route`
(true tracking error |setpoint − true position| RMS over the mission while airborne, motor chatter RMS); the
flights are one campaign (:func:`tools.campaign.engine.run_tasks`).

Keys: ``gains_vs_paper_pid_pos_rms_ratio`` and ``gains_vs_paper_pid_chatter_ratio`` (shipped / paper PID, mean
over the seeds, the larger of the two airframes; target <= 1 both and one <= 0.9), per airframe
``..._<vehicle>``, the ES-tuned PID's ratios ``es_pid_vs_paper_pid_*_<vehicle>`` and the flight counts. The
table is also written to ``results/loop_tuning/delivery_campaign.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import sys
from dataclasses import asdict
from pathlib import Path

import numpy as np
import yaml

from autopilot.control.gains import CascadeGains
from autopilot.control.param_decls import default_gains_path, shipped_gains
from tools.benchmarks import BenchResult
from tools.campaign.engine import run_tasks
from tools.research.experiments.loop_rollout import LoopOutcome, LoopRollout, fly_route
from tools.research.experiments.loop_ship import default_out_dir

VEHICLES = ("x500", "delivery650")
SETS = ("shipped", "paper_pid", "es_pid", "es_nlvg")
#: held-out seeds (the tuner trains on 1 and 2); seeds per (airframe, gain set) in a full run
FIRST_SEED = 1000
FULL_SEEDS = 34
#: campaign engine worker processes (None: one per core); flight cache (None: fly everything; ``main`` sets it)
WORKERS: int | None = None
CACHE: Path | None = None
TABLE_PATH = Path(__file__).resolve().parents[2] / "results" / "loop_tuning" / "delivery_campaign.json"


def tuned_on(vehicle: str) -> str:
    """The airframe whose closed loop the tuned candidates for ``vehicle`` came from (the shipped file's
    provenance: ``candidates_from``, else ``vehicle``)."""
    prov = yaml.safe_load(default_gains_path(vehicle).read_text()).get("provenance", {})
    return str(prov.get("candidates_from", prov.get("vehicle", vehicle)))


def gain_sets(vehicle: str, sets: tuple[str, ...] = SETS) -> dict[str, CascadeGains]:
    """The gain sets flown on ``vehicle`` (module docstring)."""
    load = {
        "shipped": lambda: shipped_gains(vehicle),
        "paper_pid": CascadeGains.fixed_pid,
        "es_pid": lambda: CascadeGains.from_yaml(default_out_dir(tuned_on(vehicle)) / "pid.yaml"),
        "es_nlvg": lambda: CascadeGains.from_yaml(default_out_dir(tuned_on(vehicle)) / "nlvg.yaml"),
    }
    return {s: load[s]() for s in sets}


def _payload_key(p: LoopRollout) -> str:
    """A flight's identity in a cache file: everything that decides the flight (airframe, gains, route, seed)."""
    return hashlib.sha256(repr(p).encode()).hexdigest()[:24]


def fly_cached(payloads: list[LoopRollout], workers: int | None, cache: Path | None) -> list[LoopOutcome]:
    """Fly ``payloads`` as one campaign; with ``cache`` (a JSON-lines file) flights already in it are read back
    and each new flight is appended as it lands (a stopped run resumes; the code version is not in the key:
    start a new file after a change)."""
    done: dict[str, LoopOutcome] = {}
    if cache is not None and cache.is_file():
        for line in cache.read_text().splitlines():
            rec = json.loads(line)
            key = rec.pop("key")  # popped first: an assignment evaluates its right-hand side before the subscript
            done[key] = LoopOutcome(**rec)
    keys = [_payload_key(p) for p in payloads]
    first: dict[str, int] = {}
    for i, k in enumerate(keys):
        first.setdefault(k, i)  # the same flight listed twice is flown once
    todo = [i for k, i in first.items() if k not in done]

    def keep(index: int, outcome: LoopOutcome) -> None:
        if cache is not None:
            with cache.open("a") as f:
                f.write(json.dumps({"key": keys[todo[index]], **asdict(outcome)}) + "\n")

    if todo:
        flown = run_tasks(
            fly_route,
            [payloads[i] for i in todo],
            workers=workers,
            key="gains-delivery",
            progress_label="delivery flights",
            on_result=keep,
        )
        done.update({keys[i]: o for i, o in zip(todo, flown, strict=True)})
    return [done[k] for k in keys]


def campaign(
    n_seeds: int,
    workers: int | None = None,
    first_seed: int = FIRST_SEED,
    vehicles: tuple[str, ...] = VEHICLES,
    sets: tuple[str, ...] = SETS,
    cache: Path | None = None,
    route: str = "delivery",
) -> tuple[dict[str, dict[str, object]], int]:
    """Fly every (vehicle, set, seed) of the delivery mission (a set equal to another on a vehicle is flown
    once); per vehicle and set: the flights' metrics, and the number of distinct flights. ``route``: another of
    ``loop_rollout.ROUTES`` (a pipeline check flies the short ``leg``)."""
    seeds = range(first_seed, first_seed + n_seeds)
    keys = [(v, s) for v in vehicles for s in sets]
    payloads = []
    for v in vehicles:
        gains = gain_sets(v, sets)
        payloads += [LoopRollout.of(v, gains[s], route, seed) for s in sets for seed in seeds]
    outcomes = fly_cached(payloads, workers, cache)
    table: dict[str, dict[str, object]] = {}
    for i, (v, s) in enumerate(keys):
        chunk = outcomes[i * n_seeds : (i + 1) * n_seeds]
        table.setdefault(v, {})[s] = {
            "flights": len(chunk),
            "completed": sum(o.completed for o in chunk),
            "diverged": sum(o.diverged for o in chunk),
            "pos_err_rms_m": [o.pos_err_rms_m for o in chunk],
            "pos_err_max_m": [o.pos_err_max_m for o in chunk],
            "chatter_rms_per_s": [o.chatter_rms_per_s for o in chunk],
        }
    return table, len({_payload_key(p) for p in payloads})


#: (set, baseline) ratios reported: against the paper PID, and the variable gain against the equally tuned PID
PAIRS = (
    ("shipped", "paper_pid"),
    ("es_pid", "paper_pid"),
    ("es_nlvg", "paper_pid"),
    ("shipped", "es_pid"),
    ("es_nlvg", "es_pid"),
)


def ratio_ci(num: list[float], den: list[float], n_boot: int = 2000) -> tuple[float, float, float]:
    """mean(num) / mean(den) over paired seeds and its 95 % bootstrap interval (seeds resampled in pairs)."""
    a, b = np.asarray(num), np.asarray(den)
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    if a.size == 0:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng(0)
    idx = rng.integers(0, a.size, size=(n_boot, a.size))
    boot = a[idx].mean(axis=1) / b[idx].mean(axis=1)
    return float(a.mean() / b.mean()), float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))


def summarise(table: dict[str, dict[str, object]]) -> dict[str, object]:
    """Per vehicle: each set's means and the ratios (with 95 % intervals) against the paper PID and the ES PID."""
    out: dict[str, object] = {}
    for v, sets in table.items():
        row: dict[str, object] = {}
        for s, d in sets.items():
            row[s] = {
                "flights": d["flights"],
                "completed": d["completed"],
                "diverged": d["diverged"],
                "pos_err_rms_m": float(np.nanmean(d["pos_err_rms_m"])),  # type: ignore[arg-type]
                "chatter_rms_per_s": float(np.nanmean(d["chatter_rms_per_s"])),  # type: ignore[arg-type]
            }
        for s, base in PAIRS:
            for metric in ("pos_err_rms_m", "chatter_rms_per_s"):
                row[f"{s}_vs_{base}_{metric}"] = ratio_ci(sets[s][metric], sets[base][metric])  # type: ignore[arg-type]
        out[v] = row
    return out


def _keys(summary: dict[str, object], n_flights: int) -> list[BenchResult]:
    res: list[BenchResult] = []
    worst = {"pos_rms": 0.0, "chatter": 0.0}
    for v, row in summary.items():
        assert isinstance(row, dict)
        for metric, short in (("pos_err_rms_m", "pos_rms"), ("chatter_rms_per_s", "chatter")):
            r, lo, hi = row[f"shipped_vs_paper_pid_{metric}"]
            worst[short] = max(worst[short], r)
            note = f"shipped / paper PID, delivery in wind, EKF, true error; 95 % CI {lo:.3f}-{hi:.3f}"
            res.append(BenchResult(f"gains_vs_paper_pid_{short}_ratio_{v}", r, "<= 1", r <= 1.0, note))
            for s, base, label in (
                ("es_pid", "paper_pid", "ES-tuned PID / paper PID"),
                ("es_nlvg", "paper_pid", "ES-tuned NLVG-PID / paper PID"),
                ("es_nlvg", "es_pid", "ES-tuned NLVG-PID / ES-tuned PID (what the variable gain adds)"),
            ):
                r, lo, hi = row[f"{s}_vs_{base}_{metric}"]
                note = f"{label}; 95 % CI {lo:.3f}-{hi:.3f}"
                res.append(BenchResult(f"{s}_vs_{base}_{short}_ratio_{v}", r, note=note))
    pos, chatter = worst["pos_rms"], worst["chatter"]
    both = pos <= 1.0 and chatter <= 1.0 and min(pos, chatter) <= 0.9
    return [
        BenchResult("gains_vs_paper_pid_pos_rms_ratio", pos, "<= 1", pos <= 1.0,
                    "shipped / paper PID true position error RMS, delivery in wind, EKF (worse airframe)"),
        BenchResult("gains_vs_paper_pid_chatter_ratio", chatter, "<= 1; one of the two <= 0.9", both,
                    "shipped / paper PID motor chatter RMS, same flights (worse airframe)"),
        BenchResult("gains_campaign_flights", n_flights, ">= 200", n_flights >= 200,
                    f"distinct seeded delivery flights: {len(VEHICLES)} airframes x {len(SETS)} gain sets"),
        *res,
    ]  # fmt: skip


def run(quick: bool) -> list[BenchResult]:
    n_seeds = 4 if quick else FULL_SEEDS
    table, n_flights = campaign(n_seeds, WORKERS, cache=CACHE)
    summary = summarise(table)
    if not quick:
        TABLE_PATH.parent.mkdir(parents=True, exist_ok=True)
        seeds = [FIRST_SEED, FIRST_SEED + n_seeds - 1]
        doc = {"mission": "missions/delivery.yaml", "estimator": "ekf", "seeds": seeds, "flights": n_flights}
        TABLE_PATH.write_text(json.dumps({**doc, "summary": summary, "flights_per_seed": table}, indent=2) + "\n")
    return _keys(summary, n_flights)


def main(argv: list[str] | None = None) -> int:
    """Fly parts of the campaign ahead into a flight cache (``--vehicles``, ``--sets``), or the whole bench suite
    with that cache (``--bench``: ``tools.benchmarks --only gains_campaign --merge``)."""
    global CACHE, WORKERS
    parser = argparse.ArgumentParser(prog="python -m tools.benchmarks.gains_campaign", description=main.__doc__)
    parser.add_argument("--cache", type=Path, required=True, help="JSON-lines flight cache (created if missing)")
    parser.add_argument("--workers", type=int, default=None, help="campaign engine worker processes")
    parser.add_argument("--vehicles", nargs="*", default=list(VEHICLES))
    parser.add_argument("--sets", nargs="*", default=list(SETS))
    parser.add_argument("--bench", action="store_true", help="run the bench suite (all flights) with the cache")
    args = parser.parse_args(argv)
    CACHE, WORKERS = args.cache, args.workers
    if args.bench:
        import tools.benchmarks.gains_campaign as suite  # the module tools.benchmarks runs (not this __main__)
        from tools.benchmarks import __main__ as bench

        suite.CACHE, suite.WORKERS = args.cache, args.workers
        return bench.main(["--only", "gains_campaign", "--merge"])
    campaign(FULL_SEEDS, args.workers, vehicles=tuple(args.vehicles), sets=tuple(args.sets), cache=args.cache)
    return 0


if __name__ == "__main__":
    sys.exit(main())

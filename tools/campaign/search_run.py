"""``quadsitl campaign search`` and ``estimate`` on the engine: the optimiser or the estimator in this process asks
for a batch of points, each point becomes an ordinary case of the campaign (:func:`~.search_space.searched_case`),
the batch is flown on one :class:`~.engine.TaskEngine` session, and every row is checkpointed (Parquet shards)
with its ``margin`` and ``replay`` command, so ``quadsitl campaign replay DIR CASE`` re-flies any of them.

``--resume`` re-runs the optimiser from the file's seed: it asks the same points in the same order, so every
batch whose rows are already in DIR is read back (its inputs checked against the asked ones) instead of flown.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tools.campaign import results
from tools.campaign.cases import materialise
from tools.campaign.engine import TaskEngine, TaskFailure
from tools.campaign.estimate import CEISResult, ce_is
from tools.campaign.objectives import Objective
from tools.campaign.report import replay_command
from tools.campaign.runner import CampaignDirError, numeric_kinds, payload_for, prepare_dir, typed_row
from tools.campaign.search import Batch, cem, cmaes, default_popsize
from tools.campaign.search_config import EstimateConfig, SearchConfig
from tools.campaign.search_space import Point, SearchSpace, searched_case, space_of
from tools.campaign.spec import CampaignSpec
from tools.campaign.task import row, run_case, versions

#: Columns a searched row has besides an ordinary case's.
SEARCH_COLUMNS = ("margin", "search_role", "search_batch", "is_log_w", "replay")


class SearchSetupError(ValueError):
    """A campaign that cannot be searched or estimated (no ``search:``), or a DIR holding other inputs."""


@dataclass(frozen=True)
class SearchOutcome:
    """What a search run did (``batches`` as the optimiser saw them) and where."""

    batches: tuple[Batch, ...]
    flown: int
    reused: int
    out_dir: Path


@dataclass(frozen=True)
class EstimateOutcome:
    result: CEISResult
    flown: int
    reused: int
    out_dir: Path


class FlightEvaluator:
    """``evaluate(first_case, points)`` for the optimisers: fly the batch's cases (or read back the rows DIR
    already has), return their margins. ``role`` is written into the rows' ``search_role``."""

    def __init__(
        self,
        spec: CampaignSpec,
        space: SearchSpace,
        objective: Objective,
        out_dir: Path,
        engine: TaskEngine,
        progress: bool,
    ) -> None:
        self.spec, self.space, self.objective, self.out_dir, self.engine = spec, space, objective, out_dir, engine
        self.progress = progress
        self.done = {int(r["case_id"]): r for r in results.read_rows(out_dir)}
        self.shards = results.ShardWriter(out_dir)
        self.kinds = numeric_kinds(spec)
        self.flown = self.reused = self.batches = 0
        self.role = "search"
        self.log_w: dict[int, float] = {}  # case id -> log importance weight (the estimate's final batch)

    def __call__(self, first_case: int, points: Sequence[Point]) -> list[float]:
        ids = [first_case + j for j in range(len(points))]
        cases = [searched_case(self.spec, self.space, k, p) for k, p in zip(ids, points, strict=True)]
        todo = [i for i, k in enumerate(ids) if k not in self.done]
        for i, k in enumerate(ids):
            if k in self.done:
                self._check(self.done[k], cases[i].overrides)
        payloads = [payload_for(self.spec, cases[i], materialise(self.spec, cases[i]), self.out_dir) for i in todo]
        rows: dict[int, dict[str, Any]] = {}

        def on_result(j: int, value: Any) -> None:
            if isinstance(value, TaskFailure):
                value = row(payloads[j], {"error": f"task failed: {value.error}"}, 0.0)
            r = self._tagged(typed_row(self.kinds, value))
            rows[int(r["case_id"])] = r
            self.shards.add(r)

        if payloads:
            label = f"{self.spec.name} {self.role} batch {self.batches}" if self.progress else None
            self.engine.run(
                run_case, payloads, key=f"{self.role}-{self.spec.name}", progress_label=label,
                on_result=on_result, on_error="return",
            )  # fmt: skip
            self.shards.flush()
        self.flown += len(payloads)
        self.reused += len(ids) - len(payloads)
        self.done.update(rows)
        self.batches += 1
        return [float(self.done[k]["margin"]) for k in ids]

    def _tagged(self, r: dict[str, Any]) -> dict[str, Any]:
        r["margin"] = self.objective.margin(r)
        r["search_role"] = self.role
        r["search_batch"] = self.batches
        r["is_log_w"] = math.nan
        r["replay"] = replay_command(self.out_dir, int(r["case_id"]))
        return r

    def _check(self, r: dict[str, Any], overrides: tuple[tuple[str, Any], ...]) -> None:
        for key, value in overrides:
            got = r.get(f"vary.{key}")
            if self.kinds.get(f"vary.{key}"):
                same = math.isclose(float(got), float(value), rel_tol=1e-12, abs_tol=1e-12)
            else:
                same = str(got) == (value if isinstance(value, str) else json.dumps(value))
            if not same:
                raise SearchSetupError(
                    f"{self.out_dir}: case {r['case_id']} was flown with {key} = {got}, the search asks {value}; "
                    "fix: resume with the campaign file and options it ran with, or use another --out"
                )

    def finish(self, meta: dict[str, str]) -> None:
        """Merge every row (those of a batch cut short by Ctrl-C included) into ``results.parquet``."""
        self.shards.flush()
        merged = {int(r["case_id"]): r for r in results.read_rows(self.out_dir)} | self.done
        for k, w in self.log_w.items():  # the final batch's weights, known once the batch is flown
            merged[k]["is_log_w"] = w
        if merged:
            _write_rows(self.out_dir, [merged[k] for k in sorted(merged)], meta)


def _write_rows(out_dir: Path, rows: list[dict[str, Any]], meta: dict[str, str]) -> None:
    """results.parquet from ``rows`` (the shards removed): one row per case id."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    shard_dir = out_dir / results.SHARD_DIR
    table = pa.Table.from_pylist(rows).replace_schema_metadata({k.encode(): v.encode() for k, v in meta.items()})
    tmp = out_dir / f".{results.RESULTS_FILE}.tmp"
    pq.write_table(table, tmp)
    tmp.replace(out_dir / results.RESULTS_FILE)
    if shard_dir.is_dir():
        for p in shard_dir.iterdir():
            p.unlink()
        shard_dir.rmdir()


def _setup(spec: CampaignSpec, out_dir: Path, resume: bool) -> tuple[SearchConfig, SearchSpace]:
    if spec.search is None:
        raise SearchSetupError(
            f"{spec.path}: no 'search:' key; fix: add search: {{objective: ..., method: cmaes}} (docs/campaigns.md)"
        )
    if spec.search.method == "cmaes":
        try:
            import cma  # noqa: F401
        except ImportError:
            raise SearchSetupError(
                "method cmaes needs pycma; fix: pip install -e '.[campaign]' (or pip install cma==4.5.0)"
            ) from None
    space = space_of(spec, spec.search.inputs)
    prepare_dir(spec, out_dir, resume)
    return spec.search, space


def _meta(spec: CampaignSpec, kind: str) -> dict[str, str]:
    return {"campaign_file": spec.text, "campaign": spec.name, "versions": versions(), "argv": json.dumps(sys.argv),
            "kind": kind}  # fmt: skip


def run_search(
    spec: CampaignSpec,
    out_dir: Path,
    *,
    budget: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> SearchOutcome:
    """Search ``spec``'s inputs for its lowest margin with at most ``budget`` (default ``cases``) flights."""
    from tools.campaign.inproc_flight import warm
    from tools.campaign.search_report import write_search_report

    search, space = _setup(spec, out_dir, resume)
    budget = budget or spec.cases
    setup = warm if spec.mode == "inproc" else None
    with TaskEngine(workers=workers, scheduler=scheduler, worker_setup=setup) as engine:
        evaluator = FlightEvaluator(spec, space, search.objective, out_dir, engine, progress)
        evaluator.role = search.method
        try:
            if search.method == "cmaes":
                popsize = search.popsize or default_popsize(space.dims)
                if popsize % engine.n_workers:
                    note = f"note: popsize {popsize} is not a multiple of the {engine.n_workers} workers"
                    print(note, file=sys.stderr)
                batches = cmaes(space, evaluator, budget=budget, popsize=popsize, seed=spec.seed, sigma0=search.sigma0)
            else:
                batches = cem(space, evaluator, budget=budget, batch=search.batch, seed=spec.seed,
                              elite_frac=search.elite_frac)  # fmt: skip
        finally:
            evaluator.finish(_meta(spec, "search"))
    outcome = SearchOutcome(tuple(batches), evaluator.flown, evaluator.reused, out_dir)
    write_search_report(spec, outcome)
    return outcome


def run_estimate(
    spec: CampaignSpec,
    out_dir: Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
    mc_dir: Path | None = None,
    mc_cases: int = 0,
) -> EstimateOutcome:
    """Estimate P(margin < 0) under the campaign's own draw by cross-entropy importance sampling; beside it the
    plain Monte Carlo of ``mc_dir`` (a campaign folder of the same file) or of ``mc_cases`` cases flown into
    ``DIR/mc``."""
    from tools.campaign.inproc_flight import warm
    from tools.campaign.search_report import write_estimate_report

    search, space = _setup(spec, out_dir, resume)
    cfg = spec.estimate or EstimateConfig()
    setup = warm if spec.mode == "inproc" else None
    with TaskEngine(workers=workers, scheduler=scheduler, worker_setup=setup) as engine:
        evaluator = FlightEvaluator(spec, space, search.objective, out_dir, engine, progress)
        evaluator.role = "ce-level"

        def final(first_case: int, points: Sequence[Point]) -> list[float]:
            evaluator.role = "is-final"
            return evaluator(first_case, points)

        try:
            result = ce_is(space, evaluator, evaluate_final=final, seed=spec.seed, **dataclasses.asdict(cfg))
            for j, w in enumerate(result.final_log_w):
                evaluator.log_w[result.final_first_case + j] = w
        finally:
            evaluator.finish(_meta(spec, "estimate"))
    mc_rows: list[dict[str, Any]] | None = None
    if mc_cases:
        from tools.campaign.runner import run_campaign

        mc_dir = out_dir / "mc"
        run_campaign(dataclasses.replace(spec, cases=mc_cases), mc_dir, workers=workers, scheduler=scheduler,
                     resume=(mc_dir / "campaign.yaml").is_file(), progress=progress)  # fmt: skip
    if mc_dir is not None:
        if not (mc_dir / results.RESULTS_FILE).is_file():
            raise CampaignDirError(f"{mc_dir}: no {results.RESULTS_FILE}; fix: give a campaign folder (--mc-dir)")
        mc_rows = results.read_rows(mc_dir)
    outcome = EstimateOutcome(result, evaluator.flown, evaluator.reused, out_dir)
    write_estimate_report(spec, outcome, mc_rows, mc_dir)
    return outcome

"""Running a campaign on the engine: materialise the cases, fan them out, checkpoint rows, merge, report.

The client (this process) draws and materialises every case (:mod:`tools.campaign.cases`), so workers get
self-contained payloads; rows come back through ``on_result`` into Parquet shards (:mod:`.results`), so a
Ctrl-C, a crash or a killed worker loses only the cases in flight and ``--resume`` completes the rest.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tools.campaign import results
from tools.campaign.cases import Case, CaseFiles, draw, materialise
from tools.campaign.engine import TaskFailure, run_tasks
from tools.campaign.spec import CampaignSpec
from tools.campaign.task import CasePayload, row, run_case, versions

CAMPAIGN_COPY = "campaign.yaml"


class CampaignDirError(ValueError):
    """The output folder cannot take this run (another campaign's results, or nothing to resume)."""


@dataclass(frozen=True)
class CampaignOutcome:
    """What a run did: cases flown now, cases skipped (already done), whether Ctrl-C stopped it."""

    flown: int
    skipped: int
    interrupted: bool
    out_dir: Path


def case_dir(out_dir: Path, case_id: int) -> Path:
    return out_dir / "cases" / f"case-{case_id:06d}"


def payload_for(
    spec: CampaignSpec, case: Case, files: CaseFiles, out_dir: Path, rerun: str | None = None
) -> CasePayload:
    return CasePayload(
        campaign=spec.name,
        root_seed=spec.seed,
        mode=spec.mode,
        estimator=spec.estimator,
        sim_time_s=spec.sim_time_s,
        deadline_s=spec.deadline_s,
        pass_if=spec.pass_if,
        case=case,
        files=files,
        case_dir=str(case_dir(out_dir, case.case_id).resolve()),
        rerun=rerun,
    )


def numeric_kinds(spec: CampaignSpec) -> dict[str, bool]:
    """Per varied dotted path's column: True when every value its distribution can draw is a number."""
    return {
        f"vary.{key}": all(isinstance(v, int | float) and not isinstance(v, bool) for v in dist.args)
        for key, dist in spec.vary
    }


def typed_row(kinds: dict[str, bool], r: dict[str, Any]) -> dict[str, Any]:
    """The row with its varied inputs in their column types (so every shard has one schema)."""
    for column, numeric in kinds.items():
        if column in r:
            r[column] = results.vary_column(numeric, r[column])
    return r


def prepare_dir(spec: CampaignSpec, out_dir: Path, resume: bool) -> set[int]:
    """Check/prepare the output folder; the case ids already done (resume)."""
    copy = out_dir / CAMPAIGN_COPY
    done = results.done_case_ids(out_dir) if out_dir.is_dir() else set()
    if resume:
        if not copy.is_file():
            raise CampaignDirError(f"{out_dir}: no campaign to resume here (no {CAMPAIGN_COPY}); fix: drop --resume")
        if copy.read_text() != spec.text:
            raise CampaignDirError(
                f"{out_dir}: holds a different campaign file than {spec.path}; fix: resume with the file it ran "
                f"({copy}) or use another --out"
            )
        return done
    if done:
        raise CampaignDirError(f"{out_dir}: already holds campaign results; fix: add --resume or use another --out")
    if copy.is_file() and copy.read_text() != spec.text:
        raise CampaignDirError(f"{out_dir}: holds another campaign file ({copy}); fix: use another --out")
    out_dir.mkdir(parents=True, exist_ok=True)
    copy.write_text(spec.text)
    return done


def run_campaign(
    spec: CampaignSpec,
    out_dir: Path,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> CampaignOutcome:
    """Fly every case of ``spec`` not yet in ``out_dir``; merge ``results.parquet`` and write the report."""
    from tools.campaign.report import write_report

    done = prepare_dir(spec, out_dir, resume)
    todo = [k for k in range(spec.cases) if k not in done]
    payloads = []
    for k in todo:
        case = draw(spec, k)
        payloads.append(payload_for(spec, case, materialise(spec, case), out_dir))
    shards = results.ShardWriter(out_dir)
    kinds = numeric_kinds(spec)

    def on_result(i: int, value: Any) -> None:
        if isinstance(value, TaskFailure):  # its worker kept dying, or the task itself broke: still a row
            value = row(payloads[i], {"error": f"task failed: {value.error}"}, 0.0)
        shards.add(typed_row(kinds, value))

    interrupted = False
    try:
        if payloads:
            from tools.campaign.inproc_flight import warm

            run_tasks(
                run_case,
                payloads,
                workers=workers,
                scheduler=scheduler,
                key=f"flight-{spec.name}",
                progress_label=f"{spec.name} ({spec.mode})" if progress else None,
                on_result=on_result,
                on_error="return",
                worker_setup=warm if spec.mode == "inproc" else None,
            )
    except KeyboardInterrupt:
        interrupted = True
    finally:
        shards.flush()
    meta = {"campaign_file": spec.text, "campaign": spec.name, "versions": versions(), "argv": json.dumps(sys.argv)}
    if results.read_rows(out_dir):
        results.merge(out_dir, meta)
        write_report(spec, out_dir)
    return CampaignOutcome(shards.written, len(done), interrupted, out_dir)

"""``quadsitl campaign replay DIR CASE``: re-fly one case from its results row, record it, check its truth hash.

The row holds the case's world, parameter and script files and its seed, so the replay needs neither the
campaign file nor its inputs. It runs here, without Dask, with a Rerun recording
(``DIR/replay/case-N/flight.rrd``), and compares the flight's truth hash (the simulator's sha256 of the state
after every control step) with the row's: equal hashes mean the same flight, bit for bit.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tools.campaign.cases import Case, CaseFiles
from tools.campaign.results import read_rows
from tools.campaign.runner import CAMPAIGN_COPY
from tools.campaign.spec import PassRule, pass_rules_of
from tools.campaign.task import CasePayload, run_case


class ReplayError(ValueError):
    """No such campaign folder or case."""


@dataclass(frozen=True)
class ReplayResult:
    matched: bool
    row: dict[str, Any]
    replayed: dict[str, Any]
    recording: Path
    text: str


def payload_from_row(
    r: dict[str, Any], case_dir: Path, mode: str, rerun: str | None, pass_if: tuple[PassRule, ...] = ()
) -> CasePayload:
    """The payload that flies the row's case again (its files, seed and run options from the row)."""
    overrides = tuple((k[len("vary.") :], v) for k, v in r.items() if k.startswith("vary."))
    case = Case(int(r["case_id"]), int(r["sim_seed"]), r["base"], r["vehicle"], r["params"], r["failures"], overrides)
    return CasePayload(
        campaign=r["campaign"],
        root_seed=int(r["root_seed"]),
        mode=mode,
        estimator=r["estimator"],
        sim_time_s=float(r["sim_time_planned_s"]),
        deadline_s=max(600.0, 3.0 * float(r["deadline_s"])),
        pass_if=pass_if,
        case=case,
        files=CaseFiles(r["world_yaml"], r["params_yaml"], r["script_yaml"]),
        case_dir=str(case_dir.resolve()),
        rerun=rerun,
    )


def replay_case(out_dir: Path, case_id: int, *, mode: str | None = None) -> ReplayResult:
    """Fly case ``case_id`` of the campaign in ``out_dir`` again (its own mode unless ``mode``)."""
    if not out_dir.is_dir():
        raise ReplayError(f"{out_dir}: no such campaign folder")
    rows = {int(r["case_id"]): r for r in read_rows(out_dir)}
    if case_id not in rows:
        have = f"{min(rows)}..{max(rows)}" if rows else "none"
        raise ReplayError(f"{out_dir}: no row for case {case_id} (cases with rows: {have})")
    r = rows[case_id]
    case_dir = out_dir / "replay" / f"case-{case_id:06d}"
    recording = case_dir / "flight.rrd"
    copy = out_dir / CAMPAIGN_COPY
    rules = pass_rules_of(copy.read_text(), copy) if copy.is_file() else ()
    replayed = run_case(payload_from_row(r, case_dir, mode or r["mode"], f"save:{recording.resolve()}", rules))
    matched = bool(r["truth_hash"]) and replayed["truth_hash"] == r["truth_hash"]
    (case_dir / "replay.json").write_text(json.dumps({k: replayed[k] for k in _SHOWN} | {"matched": matched}, indent=1))
    lines = [f"case {case_id} ({replayed['mode']}, seed {r['sim_seed']}, vehicle {r['vehicle']})"]
    lines += [f"  {k:<20} row {r.get(k)!s:<24} replay {replayed.get(k)!s}" for k in _SHOWN]
    verdict = "MATCH: the same flight, bit for bit" if matched else "MISMATCH: the replay flew a different flight"
    lines += [f"truth hash {verdict}", f"recording: {recording}   (open it with: rerun {recording})"]
    return ReplayResult(matched, r, replayed, recording, "\n".join(lines))


_SHOWN = ("status", "reason", "end_reason", "items_reached", "landed", "collisions", "tracking_pos_rms_m", "truth_hash")

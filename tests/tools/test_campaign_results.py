"""The results table (tools.campaign.results): shards merged into ``results.parquet`` one row per case id, and a
resume that flew nothing leaves the merged file byte for byte (a committed campaign folder stays clean)."""

from __future__ import annotations

from pathlib import Path

from tools.campaign.results import RESULTS_FILE, ShardWriter, merge, metadata_of, read_rows


def _write(out: Path, case_ids: list[int]) -> None:
    writer = ShardWriter(out)
    for case_id in case_ids:
        writer.add({"case_id": case_id, "status": "ok", "passed": True, "tracking_pos_rms_m": 0.1 * case_id})
    writer.flush()


def test_shards_merge_into_one_sorted_table_and_a_resume_that_flew_nothing_rewrites_nothing(tmp_path: Path) -> None:
    out = tmp_path / "camp"
    _write(out, [2, 0])
    merge(out, {"versions": "git aaaaaaa"})
    merged = out / RESULTS_FILE
    assert [r["case_id"] for r in read_rows(out)] == [0, 2] and not (out / "shards").exists()
    before = merged.read_bytes()
    merge(out, {"versions": "git bbbbbbb"})  # --resume with every case done: no shard
    assert merged.read_bytes() == before and metadata_of(merged)["versions"] == "git aaaaaaa"
    _write(out, [1])  # a resume that flew a case: merged again, with its run's metadata
    merge(out, {"versions": "git ccccccc"})
    assert [r["case_id"] for r in read_rows(out)] == [0, 1, 2] and metadata_of(merged)["versions"] == "git ccccccc"

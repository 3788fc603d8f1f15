"""The results table: rows written as Parquet shards while a campaign runs, merged into ``results.parquet``.

Shards (``DIR/shards/part-*.parquet``, each written to a temporary name and renamed) make a run resumable: an
interrupted or killed campaign loses only the cases in flight, and ``--resume`` skips every case id already in
a shard or in ``results.parquet``. The merged table has one row per case id (sorted), the campaign file and
the client's versions in its schema metadata.
"""

from __future__ import annotations

import json
import math
import os
import time
import uuid
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

RESULTS_FILE = "results.parquet"
SHARD_DIR = "shards"


def vary_column(kind_numeric: bool, value: Any) -> Any:
    """A varied input as its column stores it: a float when every value the distribution can draw is a
    number, else text (strings as they are, lists and mappings as JSON)."""
    if kind_numeric:
        return float(value)
    return value if isinstance(value, str) else json.dumps(value)


class ShardWriter:
    """Buffers rows and writes a shard every ``every_rows`` rows or ``every_s`` seconds (and on ``flush``)."""

    def __init__(self, out_dir: Path, every_rows: int = 20, every_s: float = 10.0) -> None:
        self.dir = out_dir / SHARD_DIR
        self.dir.mkdir(parents=True, exist_ok=True)
        self.every_rows, self.every_s = every_rows, every_s
        self._rows: list[dict[str, Any]] = []
        self._last = time.monotonic()
        self.written = 0

    def add(self, row: dict[str, Any]) -> None:
        self._rows.append(row)
        if len(self._rows) >= self.every_rows or time.monotonic() - self._last >= self.every_s:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows as one shard (atomic: temporary name, then rename)."""
        self._last = time.monotonic()
        if not self._rows:
            return
        table = pa.Table.from_pylist(self._rows)
        name = f"part-{min(r['case_id'] for r in self._rows):07d}-{uuid.uuid4().hex[:8]}.parquet"
        tmp = self.dir / f".{name}.tmp"
        pq.write_table(table, tmp)
        os.replace(tmp, self.dir / name)
        self.written += len(self._rows)
        self._rows = []


def _tables(out_dir: Path) -> list[pa.Table]:
    tables = []
    merged = out_dir / RESULTS_FILE
    if merged.is_file():
        tables.append(pq.read_table(merged))
    shard_dir = out_dir / SHARD_DIR
    if shard_dir.is_dir():
        tables += [pq.read_table(p) for p in sorted(shard_dir.glob("part-*.parquet"))]
    return tables


def read_rows(out_dir: Path) -> list[dict[str, Any]]:
    """Every row written so far (merged table and shards), one per case id, sorted by case id."""
    by_id: dict[int, dict[str, Any]] = {}
    for table in _tables(out_dir):
        for r in table.to_pylist():
            by_id.setdefault(int(r["case_id"]), r)
    return [by_id[k] for k in sorted(by_id)]


def done_case_ids(out_dir: Path) -> set[int]:
    """Case ids that already have a row (``--resume`` skips them)."""
    ids: set[int] = set()
    for table in _tables(out_dir):
        ids.update(int(x) for x in table.column("case_id").to_pylist())
    return ids


def merge(out_dir: Path, metadata: dict[str, str]) -> Path:
    """Write ``results.parquet`` from every shard (one row per case id, sorted), then remove the shards. With no
    shard (a ``--resume`` that flew nothing) an existing ``results.parquet`` is left as it is, byte for byte: its
    metadata keeps the versions of the run that wrote its rows, and a committed campaign folder stays clean."""
    path = out_dir / RESULTS_FILE
    if path.is_file() and not any((out_dir / SHARD_DIR).glob("part-*.parquet")):
        return path
    rows = read_rows(out_dir)
    table = pa.Table.from_pylist(rows)
    table = table.replace_schema_metadata({k.encode(): v.encode() for k, v in metadata.items()})
    tmp = out_dir / f".{RESULTS_FILE}.tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, path)
    shard_dir = out_dir / SHARD_DIR
    if shard_dir.is_dir():
        for p in shard_dir.glob("part-*.parquet"):
            p.unlink()
        for p in shard_dir.glob(".*.tmp"):
            p.unlink()
        shard_dir.rmdir()
    return path


def metadata_of(path: Path) -> dict[str, str]:
    """The schema metadata of a results file (campaign file text, versions)."""
    raw = pq.read_schema(path).metadata or {}
    return {k.decode(): v.decode() for k, v in raw.items()}


def finite(values: list[Any]) -> list[float]:
    """The finite numbers among ``values`` (NaN marks 'not measured', e.g. clearance without obstacles)."""
    return [float(v) for v in values if isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)]

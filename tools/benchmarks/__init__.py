"""Benchmark suites run by ``make bench`` (``python -m tools.benchmarks``).

Each module here exposes ``run(quick: bool) -> list[BenchResult]``; the runner prints one
table and writes ``bench/results.json`` with flat, unit-suffixed keys (SPEC §12).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class BenchResult:
    """One measured number: ``key`` is the flat JSON key with its unit in the name."""

    key: str
    value: float
    target: str = ""  # e.g. ">= 1e6"; empty when informative only
    met: bool | None = None  # None when there is no target
    note: str = ""

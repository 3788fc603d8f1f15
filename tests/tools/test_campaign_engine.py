"""The one parallel engine (tools.campaign.engine): input order, errors, Ctrl-C-free happy path, sessions."""

from __future__ import annotations

import os
import sys

import cloudpickle
import pytest

from tools.campaign.engine import TaskEngine, TaskFailedError, TaskFailure, run_tasks

# The workers are fresh processes: ship this module's task functions by value.
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def _square_slow_first(x: int) -> dict:
    import time

    time.sleep(0.3 if x == 0 else 0.0)  # the first task finishes last
    return {"x": x, "sq": x * x, "pid": os.getpid(), "hashseed": os.environ.get("PYTHONHASHSEED")}


def _fail_on_three(x: int) -> int:
    if x == 3:
        raise ValueError("three is bad")
    return x


def test_results_come_back_in_input_order_from_two_workers() -> None:
    seen: list[int] = []
    out = run_tasks(_square_slow_first, range(7), workers=2, key="sq", on_result=lambda i, r: seen.append(i))
    assert [r["sq"] for r in out] == [x * x for x in range(7)]
    assert sorted(seen) == list(range(7))
    assert len({r["pid"] for r in out}) == 2  # two worker processes did the work
    assert {r["hashseed"] for r in out} == {"0"}
    assert os.getpid() not in {r["pid"] for r in out}


def test_a_failing_task_raises_by_index_or_is_returned() -> None:
    with TaskEngine(workers=1) as engine:
        with pytest.raises(TaskFailedError, match="task 3 failed: ValueError: three is bad"):
            engine.run(_fail_on_three, range(5))
        out = engine.run(_fail_on_three, range(5), on_error="return")  # same cluster, second run
    assert out[:3] == [0, 1, 2] and out[4] == 4
    assert isinstance(out[3], TaskFailure) and out[3].index == 3 and "three is bad" in out[3].error


def test_empty_payloads_and_bad_worker_count() -> None:
    assert run_tasks(_fail_on_three, [], workers=1) == []
    with pytest.raises(ValueError, match="workers must be >= 1"):
        TaskEngine(workers=0)

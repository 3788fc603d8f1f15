"""The one parallel engine of the project: a list of independent tasks fanned out on Dask distributed.

Every Monte Carlo of quadsitl (flight campaigns, the routing and estimator Monte Carlos, the extremum-seeking
tuner's rollouts) runs through :func:`run_tasks` or a :class:`TaskEngine` session, so there is one way to go
parallel, one way to go to a cluster, and one place where faults are handled.

Contract
--------
``run_tasks(fn, payloads, *, workers=None, scheduler=None, key="task", progress_label=None, retries=0,
on_result=None, on_error="raise", worker_setup=None) -> list``

- ``fn`` is a **top-level, picklable function** of one argument (a payload) returning a picklable, small
  result (a dict of numbers, not telemetry). It runs in a Dask worker *process* with one thread: it may start
  subprocesses (``subprocess.Popen``, ideally ``start_new_session=True``) but must not use ``multiprocessing``
  (Dask workers are daemonic processes). It must not rely on global state set up by the caller.
- ``payloads`` is any iterable of picklable inputs. The result list is in **input order**, whatever order the
  tasks finished in and whichever worker ran them.
- ``workers=None`` starts an embedded ``LocalCluster`` with one single-threaded worker process per core
  (``os.cpu_count()``); ``workers=N`` starts N. ``workers=1`` still goes through Dask (one code path).
  ``scheduler="tcp://HOST:PORT"`` uses a running cluster (``dask scheduler`` / ``dask worker``) instead; its
  workers must be able to import ``fn``'s module (install quadsitl on them, same versions). An unreachable
  scheduler, or one with no worker after 60 s, raises :class:`SchedulerError`.
- Submission is bounded: at most ``2 x workers`` tasks are in the scheduler at a time, so a 100 000-task list
  costs no scheduler memory and Ctrl-C loses at most the running tasks.
- ``on_result(index, result)`` (optional) is called in the caller's process as each task finishes, in
  completion order: checkpoint there (e.g. write a shard) to make a long run resumable.
- ``retries`` re-runs a task whose ``fn`` *raised* that many more times. A task whose worker *died* (killed,
  out of memory) is re-run on another worker by Dask itself, up to ``distributed.scheduler.allowed-failures``
  (3) deaths; only the tasks that were running on that worker are lost and re-run.
- ``on_error="raise"``: the first task that still fails raises :class:`TaskFailedError` naming its index
  (the other tasks are cancelled; ``run_tasks`` closes its cluster). ``on_error="return"``: its slot in the result list
  (and the ``on_result`` call) holds a :class:`TaskFailure` instead, and the run goes on.
- ``worker_setup`` (optional, top-level picklable callable of no argument) runs once in every worker, including
  workers that join or are restarted later (a Dask ``WorkerPlugin``): warm numba kernels there.
- A rich progress bar is drawn on stderr when ``progress_label`` is given.
- Ctrl-C (KeyboardInterrupt) cancels the queued tasks, closes the client and the embedded cluster and is
  re-raised; every ``on_result`` already called stays done.
- Determinism is the task's job: derive any randomness from the payload (``numpy.random.default_rng([index,
  seed])``), never from the worker or the order. Embedded workers get ``PYTHONHASHSEED=0`` and
  ``OMP_NUM_THREADS=1`` (start ``dask worker`` processes with them if a task depends on set order or threads).

For several batches in a row (an optimiser's iterations) open the cluster once::

    with TaskEngine(workers=2) as engine:
        for it in range(n):
            costs = engine.run(rollout, payloads_of(it), key=f"rollout-{it}")
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import uuid
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Literal

from distributed import Client, LocalCluster, as_completed
from distributed.diagnostics.plugin import WorkerPlugin

ErrorPolicy = Literal["raise", "return"]
WORKER_ENV = {"PYTHONHASHSEED": "0", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


@dataclass(frozen=True)
class TaskFailure:
    """The result slot of a task that raised (after its retries) or whose workers kept dying."""

    index: int
    error: str


class TaskFailedError(RuntimeError):
    """A task failed and ``on_error="raise"``; ``index`` is its position in the payload list."""

    def __init__(self, index: int, error: str) -> None:
        super().__init__(f"task {index} failed: {error}")
        self.index = index
        self.error = error


class SchedulerError(RuntimeError):
    """The ``scheduler`` address cannot be reached, or no worker joined it in time."""


class _SetupPlugin(WorkerPlugin):
    """Runs a setup callable once in every worker, present or future."""

    idempotent = True

    def __init__(self, setup: Callable[[], None]) -> None:
        self._setup = setup
        self.name = f"quadsitl-setup-{getattr(setup, '__module__', '')}.{getattr(setup, '__qualname__', setup)}"

    def setup(self, worker: Any) -> None:
        self._setup()


def default_workers() -> int:
    """The embedded cluster's size when none is asked for: one worker per core."""
    return max(1, os.cpu_count() or 1)


class TaskEngine:
    """A Dask client (on an embedded LocalCluster or a running scheduler) kept open for several runs."""

    def __init__(
        self,
        *,
        workers: int | None = None,
        scheduler: str | None = None,
        worker_setup: Callable[[], None] | None = None,
    ) -> None:
        if workers is not None and workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self._workers = workers
        self._scheduler = scheduler
        self._worker_setup = worker_setup
        self._cluster: LocalCluster | None = None
        self.client: Client | None = None

    def __enter__(self) -> TaskEngine:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> None:
        """Connect to the scheduler, or start the embedded LocalCluster (processes, one thread each)."""
        if self.client is not None:
            return
        if self._scheduler:
            address = self._scheduler
            try:
                self.client = Client(address, timeout="30s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise SchedulerError(
                    f"no Dask scheduler at {address} ({exc}); fix: start one (dask scheduler) or check the address"
                ) from None
            try:
                self.client.wait_for_workers(1, timeout=60)
            except TimeoutError:
                self.close()
                raise SchedulerError(
                    f"the scheduler at {address} has no worker after 60 s; fix: start some (dask worker {address})"
                ) from None
        else:
            self._cluster = LocalCluster(
                n_workers=self._workers or default_workers(),
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",  # its HTTP routes on a free port (never a clash on 8787) ...
                scheduler_kwargs={"dashboard": False},  # ... and no dashboard (it needs bokeh)
                silence_logs=logging.ERROR,
                env=dict(WORKER_ENV),
            )
            self.client = Client(self._cluster)
        if self._worker_setup is not None:
            self.client.register_plugin(_SetupPlugin(self._worker_setup))

    def close(self) -> None:
        """Close the client and, if it is ours, the cluster (its worker processes end)."""
        client, cluster = self.client, self._cluster
        self.client, self._cluster = None, None
        if client is not None:
            with contextlib.suppress(Exception):  # closing a broken connection must not mask the caller's error
                client.close(timeout=10)
        if cluster is not None:
            with contextlib.suppress(Exception):
                cluster.close(timeout=20)

    def mapper(
        self, fn: Callable[[Any], Any], *, key: str, progress_label: str | None = None
    ) -> Callable[[Sequence[Any]], list[Any]]:
        """``fn`` mapped in input order on this engine, one call per batch (keys ``{key}-0``, ``{key}-1``, ...):
        the shape the tuners' rollout maps take, the same numbers as mapping ``fn`` in this process."""
        calls = itertools.count()

        def run(payloads: Sequence[Any]) -> list[Any]:
            return self.run(fn, list(payloads), key=f"{key}-{next(calls)}", progress_label=progress_label)

        return run

    @property
    def n_workers(self) -> int:
        """Workers currently connected (at least 1)."""
        assert self.client is not None, "engine not started"
        return max(1, len(self.client.scheduler_info(n_workers=-1).get("workers", {})))

    def run(
        self,
        fn: Callable[[Any], Any],
        payloads: Iterable[Any],
        *,
        key: str = "task",
        progress_label: str | None = None,
        retries: int = 0,
        on_result: Callable[[int, Any], None] | None = None,
        on_error: ErrorPolicy = "raise",
    ) -> list[Any]:
        """Run ``fn`` on every payload; results in input order (see the module docstring for the contract)."""
        if on_error not in ("raise", "return"):
            raise ValueError(f"on_error must be 'raise' or 'return', got {on_error!r}")
        self.start()
        client = self.client
        assert client is not None
        items: Sequence[Any] = payloads if isinstance(payloads, Sequence) else list(payloads)
        results: list[Any] = [None] * len(items)
        if not items:
            return results
        run_id = uuid.uuid4().hex[:10]
        window = max(2, 2 * self.n_workers)
        index_of: dict[str, int] = {}
        next_index = 0

        def submit_next(ac: as_completed) -> None:
            nonlocal next_index
            i = next_index
            next_index += 1
            fut = client.submit(fn, items[i], key=f"{key}-{run_id}-{i}", retries=retries, pure=False)
            index_of[fut.key] = i
            ac.add(fut)

        progress = _Progress(progress_label, len(items))
        ac = as_completed()
        try:
            with progress:
                while next_index < min(window, len(items)):
                    submit_next(ac)
                for fut in ac:
                    i = index_of.pop(fut.key)
                    if fut.status == "finished":
                        value = fut.result()
                    else:
                        error = _describe(fut)
                        if on_error == "raise":
                            raise TaskFailedError(i, error)
                        value = TaskFailure(i, error)
                    fut.release()
                    results[i] = value
                    if on_result is not None:
                        on_result(i, value)
                    progress.advance()
                    if next_index < len(items):
                        submit_next(ac)
        except KeyboardInterrupt:
            _cancel(client, ac)
            self.close()
            raise
        except BaseException:
            _cancel(client, ac)
            raise
        return results


def run_tasks(
    fn: Callable[[Any], Any],
    payloads: Iterable[Any],
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    key: str = "task",
    progress_label: str | None = None,
    retries: int = 0,
    on_result: Callable[[int, Any], None] | None = None,
    on_error: ErrorPolicy = "raise",
    worker_setup: Callable[[], None] | None = None,
) -> list[Any]:
    """Run ``fn(payload)`` for every payload on Dask and return the results in input order.

    Opens a :class:`TaskEngine` for this one call (an embedded LocalCluster of ``workers`` processes, or the
    cluster at ``scheduler``) and closes it afterwards; the full contract is in this module's docstring.
    """
    with TaskEngine(workers=workers, scheduler=scheduler, worker_setup=worker_setup) as engine:
        return engine.run(
            fn,
            payloads,
            key=key,
            progress_label=progress_label,
            retries=retries,
            on_result=on_result,
            on_error=on_error,
        )


def _describe(fut: Any) -> str:
    """One line saying why a future did not finish (its exception, or its status)."""
    try:
        exc = fut.exception(timeout=5)
    except Exception as err:  # a cancelled/lost future raises here
        return f"{type(err).__name__}: {err}"
    return f"{type(exc).__name__}: {exc}" if exc is not None else f"status {fut.status}"


def _cancel(client: Client, ac: as_completed) -> None:
    with contextlib.suppress(Exception):  # best effort while already unwinding
        pending = list(ac.futures)
        if pending:
            client.cancel(pending, force=True)


class _Progress:
    """A rich progress bar on stderr, or nothing when no label was given."""

    def __init__(self, label: str | None, total: int) -> None:
        self._label = label
        self._total = total
        self._bar: Any = None
        self._task: Any = None

    def __enter__(self) -> _Progress:
        if self._label is not None:
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn, TimeRemainingColumn

            self._bar = Progress(
                "[progress.description]{task.description}",
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                TimeRemainingColumn(),
                console=Console(stderr=True),
            )
            self._bar.__enter__()
            self._task = self._bar.add_task(self._label, total=self._total)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.__exit__(*exc)

    def advance(self) -> None:
        if self._bar is not None:
            self._bar.advance(self._task)

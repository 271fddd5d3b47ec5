"""Where a bench's episodes run: worker processes on this machine, or Ray tasks on a cluster.

An executor takes the jobs and yields one result per job as each finishes (in any order); a job that
raises, kills its worker, loses its node for good or overruns the wall-clock guard yields a failed
result with stage ``error`` or ``timeout``, and the batch goes on. ``skip(job)``, asked after each
result, drops the jobs no longer needed (``bench --fail-fast``): not started, they never run; under
way, they are stopped; neither yields a result.
"""

from __future__ import annotations

import multiprocessing
import os
import time
import traceback
from collections.abc import Callable, Iterator
from concurrent.futures import TimeoutError as FutureTimeout
from concurrent.futures import as_completed
from typing import Any

from pickdemo.apps.bench import DEFAULT_GUARD_S, BenchError, Job, JobFn, failed_result, run_job
from pickdemo.core.result import EpisodeRecord, Stage


class LocalExecutor:
    """Worker processes on this machine (pebble), each episode under a wall-clock guard.

    A worker whose episode overruns the guard is killed and replaced; a worker that dies (a crash in
    native code) is replaced too. Neither stops the batch. A failed episode's ``wall_time_s`` is its
    own, from when its worker started it: a worker says when it starts a job (:func:`_started_job`),
    and an episode that raises is timed and caught in its worker (:func:`_run_timed`).
    """

    def __init__(self, workers: int, guard_s: float = DEFAULT_GUARD_S, fn: JobFn = run_job) -> None:
        if workers < 1:
            raise BenchError("--workers must be at least 1")
        self.workers, self.guard_s, self.fn = workers, guard_s, fn

    def run(self, jobs: list[Job], skip: Callable[[Job], bool] | None = None) -> Iterator[EpisodeRecord]:
        from concurrent.futures import CancelledError

        from pebble import ProcessExpired, ProcessPool

        # The workers say which job each starts, and when: a pipe, drained as each job comes back (so
        # that it never fills), read for a failed job's own wall time.
        channel = multiprocessing.SimpleQueue()
        starts: dict[tuple, float] = {}

        def own_wall_s(job: Job) -> float:
            t0 = starts.get(job.key)
            return 0.0 if t0 is None else time.monotonic() - t0  # (None: its worker died before it started it)

        with ProcessPool(max_workers=self.workers, initializer=_set_channel, initargs=(channel,)) as pool:
            futures = {pool.schedule(_run_timed, args=(self.fn, job), timeout=self.guard_s): job for job in jobs}
            try:
                for fut in as_completed(futures):
                    job = futures[fut]
                    while not channel.empty():
                        key, t0 = channel.get()
                        starts[key] = t0
                    if fut.cancelled():
                        continue
                    try:
                        yield fut.result()
                    except CancelledError:
                        continue
                    except FutureTimeout:
                        yield timed_out(job, self.guard_s, max(self.guard_s, own_wall_s(job)))
                    except ProcessExpired as exc:
                        yield failed_result(job, Stage.ERROR, f"worker died (exit code {exc.exitcode})",
                                            own_wall_s(job))  # fmt: skip
                    except Exception as exc:  # noqa: BLE001 - one bad episode must not take the batch down
                        yield raised(job, exc, own_wall_s(job))
                    starts.pop(job.key, None)
                    if skip is not None:
                        for other, j in futures.items():
                            if not other.done() and skip(j):
                                other.cancel()  # (pebble stops a job under way)
            finally:
                pool.stop()


#: In a worker process of :class:`LocalExecutor`: where it says which job it starts, and when.
_CHANNEL: Any = None


def _set_channel(channel: Any) -> None:
    global _CHANNEL
    _CHANNEL = channel


def _started_job(job: Job) -> float:
    """The job's start (``time.monotonic``, one clock for every process of the machine), said to the
    executor before the episode runs, so that a worker that dies in it leaves its start behind."""
    t0 = time.monotonic()
    if _CHANNEL is not None:
        _CHANNEL.put((job.key, t0))
    return t0


def _run_timed(fn: JobFn, job: Job) -> EpisodeRecord:
    """Run one job in a worker; an episode that raises is a failed result timed from its own start."""
    t0 = _started_job(job)
    try:
        return fn(job)
    except Exception as exc:  # noqa: BLE001 - a job must always come back with a result
        return raised(job, exc, time.monotonic() - t0)


#: How long to wait for a Ray cluster's address to answer before saying it does not.
RAY_CONNECT_TIMEOUT_S = 5.0
#: How often Ray runs a task again whose worker process or node died (a node lost mid-run): an
#: episode is seeded, so its second run is the same episode. An episode that raises is not retried.
RAY_TASK_RETRIES = 3


def _reachable(address: str) -> None:
    """A ``host:port`` (or ``ray://host:port``) Ray address must answer, before Ray waits for it at
    length; ``auto`` and other forms are left to Ray."""
    rest = address.removeprefix("ray://")
    host, sep, port = rest.rpartition(":")
    if not sep or not port.isdigit() or not host:
        return
    import socket

    try:
        socket.create_connection((host, int(port)), timeout=RAY_CONNECT_TIMEOUT_S).close()
    except OSError as exc:
        raise BenchError(
            f"--address {address}: no Ray cluster answers there ({exc.strerror or exc}); start one with "
            "`ray start --head`, or leave --address out for a local Ray instance"
        ) from None


class RayExecutor:
    """Ray tasks on an existing cluster (``address``) or a local Ray instance.

    At most as many tasks are in flight as the cluster's live nodes have CPUs (counted again as
    nodes join or leave), so a task starts when it is submitted and the wall-clock guard can be
    measured from then; an overrunning task is cancelled. A task whose node died is run again on
    another (:data:`RAY_TASK_RETRIES`); what had finished was yielded already. The cluster's nodes
    need pickdemo installed (as they need any task's code).
    """

    def __init__(
        self, address: str | None, guard_s: float = DEFAULT_GUARD_S, fn: JobFn = run_job, num_cpus: int | None = None
    ) -> None:
        try:
            import ray
        except ImportError:
            raise BenchError(
                "--executor ray needs Ray: pip install -c .ci/constraints.txt '.[ray]' in the checkout"
            ) from None
        self.ray = ray
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
            address = address or os.environ.get("RAY_ADDRESS") or None
            if address is not None:
                _reachable(address)
                kwargs["address"] = address
            else:  # a new instance of its own, even where a cluster runs that Ray would join unasked
                kwargs["address"] = "local"
                if num_cpus is not None:
                    kwargs["num_cpus"] = num_cpus
            try:
                ray.init(**kwargs)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                where = f" at {address}" if address else ""
                raise BenchError(f"--executor ray: Ray did not start{where}: {_why(exc)}") from None
        self.guard_s = guard_s
        self.remote_fn = ray.remote(num_cpus=1, max_retries=RAY_TASK_RETRIES)(fn)

    def run(self, jobs: list[Job], skip: Callable[[Job], bool] | None = None) -> Iterator[EpisodeRecord]:
        ray = self.ray
        queue = list(jobs)
        in_flight: dict[Any, tuple[Job, float]] = {}
        while queue or in_flight:
            if skip is not None:
                queue = [j for j in queue if not skip(j)]
                for ref, (job, _) in list(in_flight.items()):
                    if skip(job):
                        ray.cancel(ref, force=True)
                        del in_flight[ref]
                if not queue and not in_flight:
                    break
            slots = max(1, int(ray.cluster_resources().get("CPU", 1)))  # the live nodes'
            while queue and len(in_flight) < slots:
                job = queue.pop(0)
                in_flight[self.remote_fn.remote(job)] = (job, time.perf_counter())
            done, _ = ray.wait(list(in_flight), num_returns=1, timeout=1.0)
            for ref in done:
                job, t0 = in_flight.pop(ref)
                try:
                    yield ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a task that raised or whose worker died
                    yield raised(job, exc, time.perf_counter() - t0)
            now = time.perf_counter()
            for ref, (job, t0) in list(in_flight.items()):
                if now - t0 > self.guard_s:
                    ray.cancel(ref, force=True)
                    del in_flight[ref]
                    yield timed_out(job, self.guard_s, now - t0)


def timed_out(job: Job, guard_s: float, wall_s: float) -> EpisodeRecord:
    """The result of an episode stopped by the wall-clock guard."""
    return failed_result(job, Stage.TIMEOUT, f"exceeded the wall-clock guard of {guard_s:g} s", wall_s)


def raised(job: Job, exc: BaseException, wall_s: float) -> EpisodeRecord:
    """The result of an episode whose worker raised (its first line), with where it raised: a bug (a
    worker's own traceback, where the pool passed it on as text, as pebble does)."""
    remote = getattr(exc, "traceback", None)
    where = remote if isinstance(remote, str) and remote else "".join(traceback.format_exception(exc))
    return failed_result(job, Stage.ERROR, f"{type(exc).__name__}: {exc}".splitlines()[0], wall_s, where)


def _why(exc: BaseException) -> str:
    """Ray's reason in one line; a cluster that wants a token this process was not given says so."""
    if any("Authentication token" in str(e) for e in (exc, exc.__cause__, exc.__context__) if e is not None):
        return (
            "the cluster wants an authentication token: give this process the head's (RAY_AUTH_MODE=token, "
            "and the token in ~/.ray/auth_token or RAY_AUTH_TOKEN)"
        )
    return str(exc).splitlines()[0]

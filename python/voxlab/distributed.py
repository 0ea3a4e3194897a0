"""`voxlab.ablate(..., executor="ray")`: an ablation's tasks on a Ray cluster.

The sweep is the one `voxlab ablate` runs (`src/ablate/tasks.rs`): a list of tasks,
each a band of rows of one half of a converged reference or one point with all its
seeds. This module hands them to Ray and gives their outputs back to the driver
(`_native.AblateDriver`), which assembles the references, measures every point and
writes the same files a local run writes. docs/ray.md says how to run it on a
multi-GPU machine and on a cluster, and what it costs.

Resources: each point worker is an actor that keeps one tracer (its pipelines compile
once) and asks for `num_gpus=1` when the sweep renders on the GPU and the cluster has
GPUs; the f64 reference's bands are then tasks of their own asking for one CPU each.
On a cluster without GPUs (or a CPU sweep) the same CPU workers do both.

Faults: a worker process that dies mid-task is restarted and its task retried by Ray
(`max_restarts`, `max_task_retries`, `max_retries`); a task that fails for a reason of
the experiment (a VoxlabError) is not retried: the sweep stops and raises it once. Every
point done is kept in the driver's cache, so `resume=True` renders only what is missing.
"""

from __future__ import annotations

import json
import os
import socket
from typing import Any, Callable, Optional

from . import _native

# How often Ray restarts a dead worker and retries its task before the sweep fails.
RETRIES = 3

# Per (path, overrides, text): the CPU worker a process keeps for reference bands.
_band_workers: dict = {}


def _band_worker(path: str, sets: tuple, text: Optional[str]) -> Any:
    key = (path, sets, text)
    if key not in _band_workers:
        _band_workers[key] = _native.AblateWorker(path, list(sets), cpu_only=True, text=text)
    return _band_workers[key]


class _PointWorker:
    """One Ray actor: a voxlab tracer kept across the tasks it is given."""

    def __init__(self, path: str, sets: list, cpu_only: bool, text: Optional[str] = None):
        self.worker = _native.AblateWorker(path, sets, cpu_only=cpu_only, text=text)
        self.calls = 0

    def labels(self) -> tuple:
        return self.worker.adapter, self.worker.reference_label

    def run(self, task: str) -> bytes:
        self.calls += 1
        return self.worker.run(task)

    def stats(self) -> tuple:
        """(process id, tasks this actor process was given): a restarted actor starts
        again at zero."""
        return os.getpid(), self.calls


def actor_options(use_gpus: bool, threads: int) -> dict:
    """The point workers' Ray options: restarted and their task retried when the
    process dies, never retried for an exception the task raised (an experiment's
    error); one GPU each on a GPU sweep, else one CPU; `threads` rayon threads."""
    options: dict = {
        "max_restarts": RETRIES,
        "max_task_retries": RETRIES,
        "runtime_env": {"env_vars": {"RAYON_NUM_THREADS": str(threads)}},
    }
    if use_gpus:
        options["num_gpus"] = 1
        # The GPU is the worker's resource; the CPUs stay free for the reference's bands.
        options["num_cpus"] = 0
    else:
        options["num_cpus"] = 1
    return options


def _run_band(path: str, sets: tuple, task: str, text: Optional[str] = None) -> bytes:
    return _band_worker(path, sets, text).run(task)


# Seconds to wait for a cluster's head to answer before saying it cannot be reached:
# ray.init retries an unreachable address for minutes.
CONNECT_TIMEOUT_S = 10.0


def _reachable(address: str) -> None:
    """A VoxlabError unless HOST:PORT accepts a connection within CONNECT_TIMEOUT_S
    ("auto", and "ray://" client addresses, are Ray's to resolve: they fail fast)."""
    if address == "auto" or "://" in address:
        return
    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit() or not 0 < int(port) < 65536:
        raise _native.VoxlabError(
            f"address {address!r}: expected HOST:PORT (the head's GCS port, 6379 by "
            'default), "auto", or ray://HOST:PORT'
        )
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=CONNECT_TIMEOUT_S).close()
    except OSError as e:
        raise _native.VoxlabError(
            f"address {address!r}: no Ray cluster answers there ({e}); start one with "
            "`ray start --head` (docs/ray.md)"
        ) from None


def _unwrap(err: BaseException) -> BaseException:
    """The VoxlabError inside a Ray task error, so the caller sees what a local run
    would raise."""
    cause = getattr(err, "cause", None)
    if isinstance(cause, BaseException):
        return cause
    try:
        inner = err.as_instanceof_cause()  # type: ignore[attr-defined]
    except Exception:
        return err
    return inner if isinstance(inner, BaseException) else err


def ablate_on_ray(
    path: str,
    sets: list,
    out: str,
    cache: Optional[str],
    *,
    address: Optional[str] = None,
    workers: Optional[int] = None,
    bands: Optional[int] = None,
    resume: bool = False,
    progress: Optional[Callable[[int, int], Any]] = None,
    text: Optional[str] = None,
) -> tuple:
    """Runs the sweep on Ray: (files written, tasks done, points resumed). Connects to
    `address` (a running cluster, or "auto"), or starts a local cluster when Ray is not
    initialised and no address is given; a cluster it started is shut down at the end."""
    try:
        import ray
    except ImportError as e:
        raise _native.VoxlabError(
            "executor=\"ray\" needs Ray: pip install \"ray>=2.40\" (docs/ray.md)"
        ) from e

    started = False
    if not ray.is_initialized():
        kwargs: dict = {"include_dashboard": False, "log_to_driver": False}
        if address is not None:
            _reachable(address)
            kwargs["address"] = address
        try:
            ray.init(**kwargs)
        except ConnectionError as e:
            raise _native.VoxlabError(
                f"address {address!r}: {e} (docs/ray.md: ray start --head)"
            ) from None
        started = True
    actors: list = []
    try:
        resources = ray.cluster_resources()
        gpus = int(resources.get("GPU", 0))
        cpus = max(1, int(resources.get("CPU", 1)))
        # A point worker on a GPU when the sweep renders on one and the cluster has one;
        # a CPU sweep, or a cluster without GPUs (a software driver), uses CPU workers.
        # Read here first, the experiment's errors come before any worker starts.
        probe = _native.AblateWorker(path, list(sets), cpu_only=True, text=text)
        use_gpus = gpus > 0 and probe.backend != "cpu"
        # The f64 reference's bands go to CPU tasks beside GPU workers; a GPU reference
        # renders each half whole on a point worker.
        cpu_bands = use_gpus and probe.reference_backend == "cpu"
        n = workers if workers is not None else (gpus if use_gpus else cpus)
        if n < 1:
            raise _native.VoxlabError(f"workers = {n}: at least one worker is needed")
        threads = 1 if use_gpus else max(1, cpus // n)
        actor_class = ray.remote(_PointWorker).options(**actor_options(use_gpus, threads))
        actors = [actor_class.remote(path, list(sets), False, text) for _ in range(n)]
        labels = ray.get([a.labels.remote() for a in actors])
        adapters = sorted({a for a, _ in labels})
        reference_labels = {r for _, r in labels}
        if len(reference_labels) != 1:
            raise _native.VoxlabError(
                "the workers' reference renderers differ ({}): a reference's cache key "
                "names its renderer, so one sweep needs one kind".format(
                    ", ".join(sorted(reference_labels))
                )
            )
        driver = _native.AblateDriver(
            path, list(sets), out, reference_labels.pop(), cache=cache, resume=resume,
            text=text,
        )
        # Bands: enough for every worker (or CPU) to take several, so a slow band does
        # not hold the reference up.
        todo = driver.tasks(bands if bands is not None else max(4, 2 * max(n, cpus)))
        band = ray.remote(_run_band).options(
            num_cpus=1,
            max_retries=RETRIES,
            retry_exceptions=False,
            runtime_env={"env_vars": {"RAYON_NUM_THREADS": "1"}},
        )
        sets_key = tuple(sets)
        pending: dict = {}
        queue = list(todo)
        busy = {i: 0 for i in range(n)}
        # Each actor holds at most two tasks, so one that dies loses little and the
        # others take the queue.
        depth = 2

        def submit() -> None:
            while queue:
                task = queue[0]
                is_band = json.loads(task)["kind"] == "reference-tile"
                if is_band and cpu_bands:
                    queue.pop(0)
                    pending[band.remote(path, sets_key, task, text)] = (task, None)
                    continue
                free = [i for i in range(n) if busy[i] < depth]
                if not free:
                    return
                i = min(free, key=lambda k: busy[k])
                queue.pop(0)
                busy[i] += 1
                pending[actors[i].run.remote(task)] = (task, i)

        total = len(todo)
        done = 0
        if progress is not None:
            progress(0, total)
        submit()
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            ref = ready[0]
            task, i = pending.pop(ref)
            if i is not None:
                busy[i] -= 1
            try:
                output = ray.get(ref)
            except ray.exceptions.RayTaskError as e:
                raise _unwrap(e) from None
            driver.put(output)
            done += 1
            if progress is not None:
                progress(done, total)
            submit()
        resumed = driver.resumed
        files = driver.finish("; ".join(adapters) + f" (ray, {n} workers)")
        return files, total, resumed
    finally:
        for a in actors:
            try:
                ray.kill(a)
            except Exception:
                pass
        if started:
            ray.shutdown()

"""Where a campaign's jobs run: a local process pool (:class:`LocalExecutor`) or Ray
(:class:`RayExecutor`); :func:`make_executor` picks one. Both map a function over job dicts and
yield the results as they finish; an interrupt cancels what is queued."""

from __future__ import annotations

import multiprocessing as mp
import os
import queue
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from attitude_envs.registration import quiet_version_warnings
from experiments.campaign.spec import Campaign
from experiments.processes import die_with_parent, pin_to_one_core, pool_context
from experiments.training.algorithm import Algorithm
from experiments.training.hyperparams import load_hyperparams


def _init_worker(parent_pid: int, counter) -> None:
    """Pool-worker initializer: Ctrl-C is the parent's and the worker dies with it
    (:func:`die_with_parent`); with a ``counter``, worker ``i`` runs on CPU ``i`` of the allowed
    ones (:func:`pin_to_one_core`: one JAX thread pool per worker, no contention between workers)."""
    die_with_parent(parent_pid)
    quiet_version_warnings()
    if counter is not None:
        with counter.get_lock():
            index = counter.value
            counter.value += 1
        pin_to_one_core(index)


class LocalExecutor:
    """Runs jobs in a local process pool (``workers`` > 1) or inline (``workers`` = 1).

    The workers die with this process, also on SIGKILL (:func:`experiments.processes.die_with_parent`). On an interrupt
    (Ctrl-C) or any other exception, and on :meth:`close`, pending jobs are cancelled and the
    workers terminated at once instead of finishing their jobs."""

    def __init__(self, workers: int | None = None, pin: bool = False) -> None:
        self.workers = max(1, int(workers or os.cpu_count() or 1))
        self.pin = bool(pin)  # each worker on its own CPU (campaigns that train with SBX)
        self.name = f"local-pool[{self.workers}]"
        self._pool: ProcessPoolExecutor | None = None
        self._children: list = []

    def map_unordered(self, fn: Callable, jobs: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
        if self.workers == 1 or len(jobs) <= 1:
            for job in jobs:
                yield fn(job)
            return
        before = {p.pid for p in mp.active_children()}
        context = pool_context()
        self._pool = pool = ProcessPoolExecutor(
            max_workers=min(self.workers, len(jobs)),
            mp_context=context,
            initializer=_init_worker,
            initargs=(os.getpid(), context.Value("i", 0) if self.pin else None),
        )
        try:
            # Results arrive through done-callbacks, not concurrent.futures.wait: wait() takes every
            # pending future's lock in a Python loop, a Ctrl-C inside that loop leaves some of them
            # held, the pool's manager thread then blocks for ever in set_result, and interpreter
            # exit (which joins that thread) hangs after the interrupt message
            # (once in 47 Ctrl-Cs of a stress loop with 2 workers).
            finished: queue.SimpleQueue = queue.SimpleQueue()
            futures = [pool.submit(fn, job) for job in jobs]
            self._children = [p for p in mp.active_children() if p.pid not in before]
            for fut in futures:
                fut.add_done_callback(finished.put)
            for _ in futures:
                yield finished.get().result()
        except BaseException:  # interrupt, a failed job, or the consumer stopped (GeneratorExit)
            self._terminate()
            raise
        pool.shutdown(wait=True)
        self._pool = None

    def _terminate(self) -> None:
        """Cancel what is queued and end the workers now (SIGTERM, then SIGKILL after 1 s)."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        pool.shutdown(wait=False, cancel_futures=True)
        for p in self._children:
            if p.is_alive():
                p.terminate()
        deadline = time.monotonic() + 1.0
        for p in self._children:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(0.5)
        self._children = []

    def close(self) -> None:
        self._terminate()


class RayExecutor:
    """Runs jobs as Ray tasks (``address="local"`` starts a local instance on loopback)."""

    def __init__(self, address: str, num_cpus: int | None = None) -> None:
        try:
            import ray  # optional: the ray extra
        except ImportError as exc:
            raise ValueError("--ray needs the optional extra 'ray' (pip install attitude-envs[ray])") from exc
        root = str(Path(__file__).resolve().parents[2])  # the repository root: workers import experiments
        runtime_env = {"env_vars": {"PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}}
        self._started = not ray.is_initialized()
        if self._started:
            if address == "local":
                ray.init(
                    num_cpus=num_cpus or os.cpu_count(),
                    include_dashboard=False,
                    runtime_env=runtime_env,
                    log_to_driver=False,
                    _node_ip_address="127.0.0.1",
                )
            else:
                try:
                    ray.init(address=address, runtime_env=runtime_env, log_to_driver=False)
                except ConnectionError as exc:  # one line, not ray's traceback
                    raise ValueError(
                        f"--ray {address!r}: no Ray cluster answers at that address ({str(exc).splitlines()[0]}); "
                        "start one with 'ray start --head' and pass its address (or 'auto'), or use --ray local"
                    ) from None
        self._ray = ray
        self.name = f"ray[{address}]"

    def map_unordered(self, fn: Callable, jobs: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
        ray = self._ray
        remote = ray.remote(num_cpus=1)(fn)
        pending = [remote.remote(job) for job in jobs]
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    yield ray.get(ref)
        except BaseException:  # interrupt or a failed job: cancel what is still queued or running
            for ref in pending:
                ray.cancel(ref, force=True)
            raise

    def close(self) -> None:
        if self._started:
            self._ray.shutdown()


def make_executor(ray_address: str | None = None, workers: int | None = None, pin: bool = False):
    """Ray (``ray_address``) or the local pool; ``pin``: each local worker on its own CPU."""
    return LocalExecutor(workers, pin) if not ray_address else RayExecutor(ray_address, workers)


def executor_name(ray_address: str | None = None, workers: int | None = None) -> str:
    """The name :func:`make_executor` gives its executor (without starting it)."""
    return f"ray[{ray_address}]" if ray_address else LocalExecutor(workers).name


def trains_with_sbx(campaign: Campaign) -> bool:
    """Whether any training job of ``campaign`` runs on JAX: SBX or the fused ``jax`` backend (its
    ``train.backend``, else its hyperparameter entry's; their workers are pinned to one CPU each)."""
    for env in campaign.envs:
        for agent in campaign.agents_for(env):
            t = agent.train
            if t is None:
                continue
            env_id = agent.env_id or env.id  # an agent training on its own task uses that task's entry
            entry = load_hyperparams(t["algo"], env_id, t.get("hyperparams_file"), t.get("overrides"))
            if Algorithm(t["algo"], t.get("backend", entry.get("backend", "sb3"))).backend in ("sbx", "jax"):
                return True
    return False

"""Independent tasks on the sweep's backends: in this process, a local process pool, or a Ray cluster."""

from __future__ import annotations

from typing import Any, Callable

from .errors import ConfigError

BACKENDS = ("local", "ray")


def run_tasks(function: Callable, tasks: list[tuple], backend: str = "local", workers: int = 1) -> list[Any]:
    """`function(*task)` for every task, results in task order: on Ray (RAY_ADDRESS, or a local one), else on
    `workers` local processes (forked: what this process has built they have too), or here with one worker."""
    if backend == "ray":
        try:
            import ray
        except ImportError:
            raise ConfigError("--backend ray needs Ray: pip install ray (or pip install 'fusionkit[scale]')") from None
        if not ray.is_initialized():
            ray.init(ignore_reinit_error=True, include_dashboard=False, log_to_driver=False, logging_level="error")
        remote = ray.remote(num_cpus=1)(function)
        return ray.get([remote.remote(*task) for task in tasks])
    if workers <= 1 or len(tasks) <= 1:
        return [function(*task) for task in tasks]
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(min(workers, len(tasks))) as pool:
        return list(pool.map(function, *zip(*tasks)))

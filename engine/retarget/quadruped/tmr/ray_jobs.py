"""Where long retargeting work runs: in this process, or on Ray (a local Ray by default, a cluster with an address).

Both executors have the same three verbs the Bayesian optimisation and the batch command use: ``submit`` a
function call (returns a handle), ``collect`` finished ones (blocks until at least one is done), ``cancel``
running ones. No home-made process pool: parallelism is Ray's.
"""

from __future__ import annotations

import os
from typing import Any, Callable

from engine.ray_cluster import connect_ray


class LocalExecutor:
    """Runs each call at submit time, in this process (tests, one-core runs, inside a Ray worker)."""

    def __init__(self) -> None:
        self._done: dict[int, tuple[Any, BaseException | None]] = {}
        self._next = 0

    def submit(self, fn: Callable, *args: Any, **kwargs: Any) -> int:
        handle = self._next
        self._next += 1
        try:
            self._done[handle] = (fn(*args, **kwargs), None)
        except BaseException as exc:  # noqa: BLE001 - re-raised at collect
            self._done[handle] = (None, exc)
        return handle

    def collect(self, handles: list[int]) -> list[tuple[int, Any]]:
        out = []
        for h in handles:
            value, exc = self._done.pop(h)
            if exc is not None:
                raise exc
            out.append((h, value))
        return out

    def cancel(self, handles: list[int]) -> None:
        for h in handles:
            self._done.pop(h, None)

    @property
    def workers(self) -> int:
        return 1


class RayExecutor:
    """Ray tasks; ``address`` None starts a local Ray with ``num_cpus`` workers (a Ray already initialised in this
    process is used as it is), else joins that cluster: :mod:`engine.ray_cluster`, which raises ``RayClusterError``."""

    def __init__(self, address: str | None = None, num_cpus: int | None = None):
        self._ray = connect_ray(address, num_cpus=num_cpus or os.cpu_count() or 1)
        self._remote: dict[Callable, Any] = {}

    def submit(self, fn: Callable, *args: Any, **kwargs: Any) -> Any:
        remote = self._remote.get(fn)
        if remote is None:
            remote = self._remote[fn] = self._ray.remote(num_cpus=1)(fn)
        return remote.remote(*args, **kwargs)

    def collect(self, handles: list[Any]) -> list[tuple[Any, Any]]:
        done, _ = self._ray.wait(handles, num_returns=1)
        return [(h, self._ray.get(h)) for h in done]

    def cancel(self, handles: list[Any]) -> None:
        for h in handles:
            self._ray.cancel(h, force=True)

    @property
    def workers(self) -> int:
        return int(self._ray.cluster_resources().get("CPU", 1))

    def shutdown(self) -> None:
        self._ray.shutdown()

"""Where long retargeting work runs: in this process, or on Ray (a local Ray by default, a cluster with an address).

Both executors have the same three verbs the Bayesian optimisation and the batch command use: ``submit`` a
function call (returns a handle), ``collect`` finished ones (blocks until at least one is done), ``cancel``
running ones. No home-made process pool: parallelism is Ray's.
"""

from __future__ import annotations

import socket
from typing import Any, Callable


START_ATTEMPTS = 2  # a loaded machine can miss Ray's fixed 30 s node start-up window once


class RayAddressError(RuntimeError):
    """A Ray address that does not answer (one line)."""


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


def check_address(address: str, timeout_s: float = 3.0) -> None:
    """Fail fast (one line) when nothing listens at a Ray address ``host:port`` or ``ray://host:port``."""
    if address in ("auto", "local"):
        return
    hostport = address.split("://", 1)[-1]
    host, _, port = hostport.rpartition(":")
    if not host or not port.isdigit():
        raise RayAddressError(f"--address: expected host:port or ray://host:port, got {address!r}")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s):
            pass
    except OSError as exc:
        raise RayAddressError(f"--address {address}: no Ray head answers ({exc.strerror or type(exc).__name__})") from None


class RayExecutor:
    """Ray tasks; ``address`` None starts (or joins) a local Ray with ``num_cpus`` workers."""

    def __init__(self, address: str | None = None, num_cpus: int | None = None):
        import os

        import ray

        if address is not None:
            check_address(address)
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False, "ignore_reinit_error": True,
                                      "configure_logging": False}
            if address is None:
                kwargs["num_cpus"] = num_cpus or os.cpu_count() or 1
                repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))))
                kwargs["runtime_env"] = {"env_vars": {"PYTHONPATH": os.pathsep.join(
                    p for p in [repo, os.environ.get("PYTHONPATH", "")] if p)}}
            else:
                kwargs["address"] = address
            for attempt in range(START_ATTEMPTS):
                try:
                    ray.init(**kwargs)
                    break
                except Exception as exc:  # noqa: BLE001 - Ray raises bare Exception when its node times out
                    ray.shutdown()
                    if attempt + 1 == START_ATTEMPTS:
                        where = f"--address {address}: " if address else "local Ray: "
                        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                        raise RayAddressError(f"{where}Ray did not start ({first})") from None
        self._ray = ray
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

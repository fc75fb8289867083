"""Where the engine's batch work gets its Ray: a local Ray started on this machine, or a cluster joined at an address.

Every command that runs on Ray (``studio library``, ``tmr`` / ``retarget-batch`` / ``retarget --method stmr``,
``bench styles`` / ``push`` / ``tmr``) connects through :func:`connect_ray`, so they all behave alike:

* no address (or ``"local"``): a new local Ray, even when ``ray start`` runs a cluster on this machine (join that
  one with ``"auto"``), with the workers' ``PYTHONPATH`` set to this repository, no dashboard, the workers' output
  not copied to this terminal; the start is tried ``START_ATTEMPTS`` times (a local raylet that takes more than
  Ray's fixed 30 s to register on a loaded machine fails an attempt). An address in ``RAY_ADDRESS`` counts as
  ``address`` (Ray itself would join it).
* ``host:port`` (a ``ray start --head`` node) or ``ray://host:port`` (Ray Client): checked first with a plain TCP
  connect (:func:`check_address`, a few seconds, instead of Ray's long time-outs), then joined with the repository
  shipped as the job's working directory. ``"auto"`` is Ray's own discovery of a cluster on this machine.
* Token authentication (Ray ≥ 2.52; ``ray start`` turns it on when a token exists, Ray 2.60): Ray's driver sends its
  token only with ``RAY_AUTH_MODE=token`` in its environment, and ``ray.init`` sets that by itself only for a local
  start or ``"auto"``. For an explicit address :func:`enable_token_auth` sets it when the variable is unset and a
  token is found where Ray looks for one (``RAY_AUTH_TOKEN``, the file named by ``RAY_AUTH_TOKEN_PATH``,
  ``~/.ray/auth_token``), so ``--address`` works without the user exporting anything.

Every failure is :class:`RayClusterError`, one line naming the address and what was expected.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path
from types import ModuleType
from typing import Any

REPO_ROOT = Path(__file__).resolve().parent.parent
START_ATTEMPTS = 3  # a loaded machine can miss Ray's fixed 30 s node start-up window once or twice
REACH_TIMEOUT_S = 3.0  # a head that does not accept a TCP connection in this long is taken as absent
# what a cluster's workers need of the repository: the code and the robot, style and motion descriptions
SHIPPED_EXCLUDES = (".git", ".venv", "docs", "tests", "*.npz")
AUTH_MODE_ENV = "RAY_AUTH_MODE"
EXPECTED = "expected a running Ray head (`ray start --head`) at host:port, or ray://host:port for Ray Client"


class RayClusterError(RuntimeError):
    """Ray could not be started or reached (one line, naming the address)."""


def check_address(address: str, timeout_s: float = REACH_TIMEOUT_S) -> None:
    """Fail fast when nothing accepts a TCP connection at ``host:port`` or ``ray://host:port``.

    ``"auto"`` and ``"local"`` are Ray's own (discover a cluster on this machine / start one) and pass."""
    if address in ("auto", "local"):
        return
    host, port = _host_port(address)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:
        reason = exc.strerror or (f"no answer in {timeout_s:g} s" if isinstance(exc, TimeoutError) else type(exc).__name__)
        raise RayClusterError(f"--address {address}: no Ray head answers ({reason}); {EXPECTED}") from None


def _host_port(address: str) -> tuple[str, int]:
    scheme, sep, hostport = address.partition("://")
    if not sep:
        scheme, hostport = "", address
    host, _, port = hostport.rstrip("/").rpartition(":")
    host = host.strip("[]")  # [::1]:6379
    if scheme not in ("", "ray") or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise RayClusterError(f"--address: expected host:port, ray://host:port or auto, got {address!r}")
    return host, int(port)


def token_available() -> bool:
    """Whether Ray finds an authentication token here (``RAY_AUTH_TOKEN``, ``RAY_AUTH_TOKEN_PATH``,
    ``~/.ray/auth_token``), whatever ``RAY_AUTH_MODE`` says. False for a Ray without token authentication."""
    try:
        from ray._raylet import AuthenticationTokenLoader  # type: ignore[attr-defined]  # compiled, no stub
    except ImportError:
        return False
    return bool(AuthenticationTokenLoader.instance().has_token(ignore_auth_mode=True))


def enable_token_auth() -> bool:
    """Set ``RAY_AUTH_MODE=token`` for this driver (and the processes it starts) when the variable is unset and a
    token is available; what ``ray.init`` itself does for a local cluster, not for an explicit address. Returns
    whether token authentication is on. An explicit ``RAY_AUTH_MODE`` is left as it is."""
    mode = os.environ.get(AUTH_MODE_ENV)
    if mode is not None:
        return mode.lower() == "token"
    if not token_available():
        return False
    os.environ[AUTH_MODE_ENV] = "token"
    from ray._raylet import Config  # type: ignore[attr-defined]

    Config.initialize("")  # Ray's configuration is cached: read the environment again (as Ray does)
    return True


def connect_ray(address: str | None = None, num_cpus: int | None = None,
                worker_niceness: int | None = None) -> ModuleType:
    """Start a local Ray (``address`` None) or join the cluster at ``address``; return the ``ray`` module, ready.

    A Ray already initialised in this process is used as it is. ``num_cpus`` (local only) caps the workers (default:
    every CPU); ``worker_niceness`` (local only) replaces Ray's default niceness of 15 for its workers (0: on a
    shared machine they would otherwise wait behind everything else). Raises :class:`RayClusterError`."""
    import ray

    if ray.is_initialized():
        return ray
    address = address or os.environ.get("RAY_ADDRESS") or None
    if address == "local":
        address = None
    kwargs: dict[str, Any] = {"log_to_driver": False, "configure_logging": False}
    if address is None:
        # "local": a new Ray of our own, even when `ray start` left a cluster on this machine (ray.init() without an
        # address would join that one, where num_cpus and the rest are refused)
        kwargs["address"] = "local"
        kwargs["include_dashboard"] = False
        kwargs["runtime_env"] = {"env_vars": {"PYTHONPATH": os.pathsep.join(
            p for p in (str(REPO_ROOT), os.environ.get("PYTHONPATH", "")) if p)}}
        if num_cpus is not None:
            kwargs["num_cpus"] = num_cpus
        if worker_niceness is not None:
            kwargs["_system_config"] = {"worker_niceness": worker_niceness}
        _init(ray, kwargs, "local Ray: could not start", START_ATTEMPTS)
    else:
        check_address(address)
        if address != "auto":
            enable_token_auth()
        kwargs["address"] = address
        kwargs["runtime_env"] = {"working_dir": str(REPO_ROOT), "excludes": list(SHIPPED_EXCLUDES)}
        _init(ray, kwargs, f"--address {address}: could not join the Ray cluster", 1, _token_hint())
    return ray


def _token_hint() -> str:
    """What a cluster with token authentication expects of this driver (Ray's own error does not say)."""
    if os.environ.get(AUTH_MODE_ENV, "").lower() == "token":
        return "; expected the cluster's token in RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH or ~/.ray/auth_token"
    return ("; a cluster with token authentication (`ray start` turns it on when it finds a token) expects its token "
            "in RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH or ~/.ray/auth_token (none found here)")


def _init(ray: ModuleType, kwargs: dict[str, Any], where: str, attempts: int, hint: str = "") -> None:
    last: BaseException | None = None
    for _ in range(attempts):
        try:
            ray.init(**kwargs)
            return
        except Exception as exc:  # noqa: BLE001 - Ray raises plain Exception / ConnectionError / RuntimeError here
            last = exc
            ray.shutdown()
    text = str(last).strip()
    message = text.splitlines()[0] if text else type(last).__name__
    if not ("failed to connect" in text.lower() or "auth" in text.lower()):
        hint = ""  # not a refusal Ray reports that way (a missing package, a version mismatch, ...)
    tries = f" ({attempts} attempts)" if attempts > 1 else ""
    raise RayClusterError(f"{where}{tries}: {message.rstrip('.')}{hint}")

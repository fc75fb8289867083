"""engine.ray_cluster: an address nobody listens on fails before Ray is asked (one line naming it), token
authentication is switched on for a driver that has a token, and a local Ray starts with the repository on the
workers' path and the niceness asked for."""

from __future__ import annotations

import os

import pytest

from engine import ray_cluster
from engine.ray_cluster import RayClusterError, check_address, connect_ray, enable_token_auth
from tests.conftest import free_port, run_studio

AUTH_VARIABLES = ("RAY_AUTH_MODE", "RAY_AUTH_TOKEN", "RAY_AUTH_TOKEN_PATH", "RAY_ADDRESS")


@pytest.fixture
def clean_ray_env(monkeypatch, tmp_path):  # noqa: ANN001, ANN201
    """No Ray variables and a home without ~/.ray/auth_token; Ray's cached token and configuration re-read after."""
    from ray._raylet import AuthenticationTokenLoader, Config

    for name in AUTH_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    AuthenticationTokenLoader.instance().reset_cache()
    yield monkeypatch
    monkeypatch.undo()
    AuthenticationTokenLoader.instance().reset_cache()
    Config.initialize("")


@pytest.fixture
def no_ray_init(monkeypatch):  # noqa: ANN001, ANN201
    """Fail the test if Ray is asked to connect: an unreachable address must be refused before that."""
    import ray

    def refuse(*_args, **_kwargs):  # noqa: ANN002, ANN003, ANN202
        raise AssertionError("ray.init was called for an address that does not answer")

    monkeypatch.setattr(ray, "init", refuse)


@pytest.mark.parametrize("form", ["{}", "ray://{}"])
def test_an_address_nobody_listens_on_is_refused_before_ray_is_asked(form, no_ray_init) -> None:  # noqa: ANN001
    address = form.format(f"127.0.0.1:{free_port()}")
    with pytest.raises(RayClusterError) as err:
        connect_ray(address)
    message = str(err.value)
    assert message.startswith(f"--address {address}: no Ray head answers (") and "\n" not in message
    assert "expected a running Ray head" in message


@pytest.mark.parametrize("address", ["localhost", "127.0.0.1:port", "http://127.0.0.1:6379", "127.0.0.1:70000"])
def test_a_malformed_address_names_the_expected_forms(address) -> None:  # noqa: ANN001
    with pytest.raises(RayClusterError, match=r"--address: expected host:port, ray://host:port or auto, got "):
        check_address(address)


def test_auto_is_left_to_rays_own_discovery() -> None:
    check_address("auto")  # no socket connect: Ray finds a cluster on this machine itself


def test_a_listening_head_passes_the_check() -> None:
    import socket

    with socket.socket() as head:
        head.bind(("127.0.0.1", 0))
        head.listen(1)
        check_address(f"127.0.0.1:{head.getsockname()[1]}")
        check_address(f"ray://127.0.0.1:{head.getsockname()[1]}")


def test_token_auth_is_switched_on_for_a_driver_with_a_token(clean_ray_env) -> None:  # noqa: ANN001
    from ray._raylet import AuthenticationTokenLoader

    assert not enable_token_auth() and "RAY_AUTH_MODE" not in os.environ  # no token anywhere: left alone
    home = os.environ["HOME"]
    os.makedirs(f"{home}/.ray")
    with open(f"{home}/.ray/auth_token", "w") as f:
        f.write("a" * 64)
    AuthenticationTokenLoader.instance().reset_cache()
    assert enable_token_auth() and os.environ["RAY_AUTH_MODE"] == "token"  # ~/.ray/auth_token, as `ray start`'s


def test_token_auth_reads_the_token_from_the_environment_too(clean_ray_env) -> None:  # noqa: ANN001
    clean_ray_env.setenv("RAY_AUTH_TOKEN", "b" * 64)
    assert enable_token_auth() and os.environ["RAY_AUTH_MODE"] == "token"


def test_an_explicit_auth_mode_is_left_as_it_is(clean_ray_env) -> None:  # noqa: ANN001
    clean_ray_env.setenv("RAY_AUTH_TOKEN", "b" * 64)
    clean_ray_env.setenv("RAY_AUTH_MODE", "disabled")
    assert not enable_token_auth() and os.environ["RAY_AUTH_MODE"] == "disabled"


@pytest.fixture
def recorded_init(monkeypatch):  # noqa: ANN001, ANN201
    """ray.init replaced by a recorder (no Ray started); ``fail`` makes it raise like Ray does for a refused join."""
    import ray

    calls: list[dict] = []
    state = {"fail": None}

    def init(**kwargs):  # noqa: ANN003, ANN202
        calls.append(kwargs)
        if state["fail"] is not None:
            raise state["fail"]

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", init)
    monkeypatch.setattr(ray, "shutdown", lambda: None)
    return calls, state


def test_a_local_start_is_a_new_ray_with_the_repository_on_the_workers_path(clean_ray_env, recorded_init) -> None:  # noqa: ANN001
    calls, _ = recorded_init
    clean_ray_env.setenv("PYTHONPATH", "/elsewhere")
    connect_ray(num_cpus=2, worker_niceness=0)
    (kwargs,) = calls
    # "local", not None: ray.init() without an address joins a cluster `ray start` left on this machine
    assert kwargs["address"] == "local" and kwargs["num_cpus"] == 2
    assert kwargs["runtime_env"] == {"env_vars": {"PYTHONPATH": f"{ray_cluster.REPO_ROOT}{os.pathsep}/elsewhere"}}
    assert kwargs["_system_config"] == {"worker_niceness": 0}
    assert not kwargs["include_dashboard"] and not kwargs["log_to_driver"] and not kwargs["configure_logging"]


def test_a_local_start_is_tried_again_then_one_line(clean_ray_env, recorded_init) -> None:  # noqa: ANN001
    calls, state = recorded_init
    state["fail"] = Exception("The current node timed out during startup.\nmore of Ray's text")
    with pytest.raises(RayClusterError) as err:
        connect_ray()
    assert len(calls) == ray_cluster.START_ATTEMPTS
    assert str(err.value) == (f"local Ray: could not start ({ray_cluster.START_ATTEMPTS} attempts): "
                              "The current node timed out during startup")


def test_a_cluster_is_joined_with_the_repository_shipped_and_the_token_switched_on(clean_ray_env,
                                                                                  recorded_init) -> None:  # noqa: ANN001
    import socket

    calls, _ = recorded_init
    clean_ray_env.setenv("RAY_AUTH_TOKEN", "c" * 64)
    with socket.socket() as head:
        head.bind(("127.0.0.1", 0))
        head.listen(1)
        address = f"127.0.0.1:{head.getsockname()[1]}"
        connect_ray(address, num_cpus=2)
    (kwargs,) = calls
    assert kwargs["address"] == address and "num_cpus" not in kwargs  # a cluster's CPUs are its own
    assert kwargs["runtime_env"] == {"working_dir": str(ray_cluster.REPO_ROOT),
                                     "excludes": [".git", ".venv", "docs", "tests", "*.npz"]}
    assert os.environ["RAY_AUTH_MODE"] == "token"


def test_a_refused_join_names_the_address_and_where_the_token_was_expected(clean_ray_env,
                                                                          recorded_init) -> None:  # noqa: ANN001
    import socket

    calls, state = recorded_init
    state["fail"] = ConnectionError("Failed to connect to Ray cluster at 192.0.2.2:6391")
    with socket.socket() as head:
        head.bind(("127.0.0.1", 0))
        head.listen(1)
        address = f"127.0.0.1:{head.getsockname()[1]}"
        with pytest.raises(RayClusterError) as err:
            connect_ray(address)
    message = str(err.value)
    assert len(calls) == 1 and "\n" not in message and "RAY_AUTH_MODE" not in os.environ  # no token here
    assert message.startswith(f"--address {address}: could not join the Ray cluster: Failed to connect to Ray cluster")
    assert "RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH or ~/.ray/auth_token (none found here)" in message


@pytest.mark.slow  # starts a local Ray (10-20 s)
def test_a_local_ray_starts_with_the_repository_on_the_workers_path(clean_ray_env) -> None:  # noqa: ANN001
    import ray

    if ray.is_initialized():
        ray.shutdown()
    try:
        assert connect_ray(num_cpus=1, worker_niceness=0) is ray and ray.is_initialized()
        assert ray.cluster_resources()["CPU"] == 1

        def worker_view() -> tuple[str, int]:
            import engine.ray_cluster

            return engine.ray_cluster.__file__, os.nice(0)

        module, niceness = ray.get(ray.remote(worker_view).remote(), timeout=300)
        assert module == ray_cluster.__file__  # this repository's engine, through PYTHONPATH
        assert niceness == os.nice(0)  # this process's niceness, not 15 more (Ray's default)
        assert connect_ray() is ray  # an initialised Ray is used as it is
    finally:
        ray.shutdown()


@pytest.mark.parametrize("command", [
    ["library", "--robot", "dino", "--grid", "vx=0"],
    ["bench", "styles"],
])
def test_the_clis_refuse_an_address_nobody_listens_on_in_one_line(command, tmp_path) -> None:  # noqa: ANN001
    address = f"127.0.0.1:{free_port()}"
    out = run_studio(*command, "--address", address, *(["--out", str(tmp_path / "lib")] if command[0] == "library"
                                                       else ["--out-dir", str(tmp_path / "bench")]), timeout=120)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and f"--address {address}: no Ray head answers" in lines[0], out.stderr
    assert list(tmp_path.iterdir()) == []

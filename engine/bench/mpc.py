"""CoM MPC bench: receding-horizon solve timing on closed-loop-like problems, and replay of
captured problems (npz, see :func:`save_problems`)."""

from __future__ import annotations

import io
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from engine.atomic_io import atomic_write_bytes
from engine.bench.mpc_problems import closed_loop_like_problems
from engine.control.mpc import ComMpc, SupportInterval


def save_problems(path: str | Path, problems: Sequence[tuple[tuple, dict]]) -> None:
    """Write ``[((t, com, vel, cop, z, supports), {}), ...]`` as flat arrays (no pickle)."""
    rows = [args for args, _ in problems]
    sizes = [len(sp.polygon) for args in rows for sp in args[5]]
    np_arrays = {
        "t_s": np.array([a[0] for a in rows], dtype=float),
        "com_xy_m": np.array([a[1] for a in rows], dtype=float).reshape(-1, 2),
        "com_vel_xy_mps": np.array([a[2] for a in rows], dtype=float).reshape(-1, 2),
        "cop_xy_m": np.array([a[3] for a in rows], dtype=float).reshape(-1, 2),
        "com_height_m": np.array([a[4] for a in rows], dtype=float),
        "support_count": np.array([len(a[5]) for a in rows], dtype=np.int64),
        "support_times_s": np.array([[sp.t_start_s, sp.t_end_s] for a in rows for sp in a[5]], dtype=float).reshape(-1, 2),
        "polygon_size": np.array(sizes, dtype=np.int64),
        "polygon_xy_m": np.concatenate([np.asarray(sp.polygon, dtype=float).reshape(-1, 2) for a in rows for sp in a[5]])
        if sizes else np.zeros((0, 2)),
    }
    buf = io.BytesIO()
    np.savez(buf, **np_arrays)  # type: ignore[arg-type]  # numpy's stub: **kwds clash with its allow_pickle: bool
    atomic_write_bytes(Path(path), buf.getvalue())


def load_problems(path: str | Path) -> list[tuple[tuple, dict]]:
    """The problems written by :func:`save_problems`."""
    with np.load(path, allow_pickle=False) as z:
        a = {k: z[k] for k in z.files}
    problems: list[tuple[tuple, dict]] = []
    s = v = 0
    for i, count in enumerate(a["support_count"]):
        supports = []
        for _ in range(int(count)):
            n = int(a["polygon_size"][s])
            t0, t1 = a["support_times_s"][s]
            supports.append(SupportInterval(float(t0), float(t1), a["polygon_xy_m"][v:v + n].copy()))
            s, v = s + 1, v + n
        problems.append(((float(a["t_s"][i]), a["com_xy_m"][i].copy(), a["com_vel_xy_mps"][i].copy(),
                          a["cop_xy_m"][i].copy(), float(a["com_height_m"][i]), supports), {}))
    return problems


def record_calls(robot_name: str = "g1", seconds: float = 4.0) -> list[tuple[tuple, dict]]:
    """Every ``ComMpc.solve`` call of a closed-loop walk (the robot's neutral style, the sweep command; restarts
    included), as :meth:`ComMpc.solve` received them (copies)."""
    from engine.control.walking_controller import WalkingController
    from engine.gait.command_schedule import preset
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import Simulation

    robot = load_robot(robot_name)
    style = load_style(styles_dir(robot_name) / "neutral.json")
    schedule = preset("sweep", style.velocities)
    ctrl = WalkingController(robot, style)
    sim = Simulation(robot, ctrl)
    calls: list[tuple[tuple, dict]] = []
    solve = ctrl.mpc.solve

    def spy(t_s, com, vel, cop, z, supports, packed=None):  # noqa: ANN001, ANN202
        # (recorded without the planner's packing: the replay's solve packs the copied supports, the same numbers)
        calls.append(((float(t_s), np.array(com, float), np.array(vel, float), np.array(cop, float), float(z),
                       [SupportInterval(s.t_start_s, s.t_end_s, np.array(s.polygon, float)) for s in supports]), {}))
        return solve(t_s, com, vel, cop, z, supports, packed)

    ctrl.mpc.solve = spy  # type: ignore[method-assign]
    dt = float(robot.mj_model.opt.timestep)
    for k in range(int(round(seconds / dt))):
        ctrl.set_command(schedule(k * dt))
        sim.step()
    return calls


def _replay(mpc: ComMpc, problems: Sequence[tuple[tuple, dict]], skip: int = 0) -> dict[str, float]:
    """Solve ``problems`` in order with ``mpc``; statistics of the calls after the first ``skip``."""
    wall_us: list[float] = []
    qp_us: list[float] = []
    iterations: list[int] = []
    statuses: list[str] = []
    for i, (args, kwargs) in enumerate(problems):
        t0 = time.perf_counter()
        sol = mpc.solve(*args, **kwargs)
        wall_s = time.perf_counter() - t0
        if i >= skip:
            wall_us.append(wall_s * 1e6)
            qp_us.append(sol.osqp_time_s * 1e6)
            iterations.append(sol.osqp_iterations)
            statuses.append(sol.status)
    wall = np.array(wall_us)
    its = np.array(iterations)
    n = len(wall)
    return {
        "n": float(n),
        "median_us": float(np.median(wall)),
        "p99_us": float(np.percentile(wall, 99)),
        "max_us": float(wall.max()),
        "mean_us": float(wall.mean()),
        "osqp_median_us": float(np.median(qp_us)),
        "median_iterations": float(np.median(its)),
        "p99_iterations": float(np.percentile(its, 99)),
        "max_iterations": float(its.max()),
        "solved_fraction": sum(s == "solved" for s in statuses) / n,
        "fallback_count": float(sum(not s.startswith("solved") for s in statuses)),
        "setup_count": float(mpc.setup_count),
    }


def benchmark_solve(
    n: int = 500,
    dt_s: float = 0.008,
    com_height_m: float = 0.6,
    seed: int = 2,
    state_noise: tuple[float, float] = (0.0, 0.0),
) -> dict[str, float]:
    """Receding-horizon solve timing on a realistic closed-loop-like walk (125 Hz re-planning).

    The problems come from :func:`closed_loop_like_problems` (varying step timing,
    moving footholds with feedback); by default the initial states continue the
    previous plan exactly, as the walking controller does (``MPC_STATE_PULL = 0``), and
    the walk stays capturable (pass ``state_noise`` for perturbed initial states).  They
    are generated first (20 start-up calls more than measured), then replayed in order
    with one fresh :class:`ComMpc` (warm starts across calls).  Returns wall-time
    statistics of ``ComMpc.solve`` in microseconds (median, p99, max, mean, QP-solver-only
    median), iteration counts (median, p99, max), the fraction of ``"solved"`` results,
    the number of fallbacks and of solver setups.
    """
    pull = 0.0 if state_noise == (0.0, 0.0) else 0.2
    problems = closed_loop_like_problems(
        n + 20, seed, dt_s=dt_s, com_height_m=com_height_m, state_noise=state_noise, pull=pull
    )
    return _replay(ComMpc(max_intervals=16), problems, skip=20)  # sized for the walk: one setup


def benchmark_captured(path: str, mpc: ComMpc | None = None) -> dict[str, float]:
    """Replay ``ComMpc.solve`` calls captured with :func:`save_problems` (an npz file), in order.

    One :class:`ComMpc` (fresh by default) solves them all, as the controller does; the
    statistics are those of :func:`benchmark_solve`, over every call.
    """
    return _replay(mpc if mpc is not None else ComMpc(), load_problems(path))

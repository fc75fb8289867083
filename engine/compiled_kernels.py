"""The engine's compiled (numba) kernels, compiled ahead of the first walk: ``make setup`` runs
:func:`warm_up` so a fresh clone pays the compilation once (≈ 15 s CPU) and every later process loads
the machine code from numba's on-disk cache (``cache=True``; ``__pycache__`` beside the sources).

Kernels: :mod:`engine.control.wbc.kernels` (the whole-body tick: the feet's frames of the snapshot, the QP's rows,
assembly, DAQP form, torques, and the one call that builds, solves and finishes a tick), the whole-body reference
between planner ticks (:mod:`engine.control.reference_kernels`),
the support polygons' convex hull (:func:`engine.geometry.polygon.convex_hull_2d`) and the gait
planner's command ramp, path table, blended channels and preview polygons (:mod:`engine.gait.planner_kernels`) and the CoM MPC's polygon geometry
(:mod:`engine.control.mpc.kernels`).
"""

from __future__ import annotations

import numpy as np


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every kernel with the argument types the controller
    passes, by running them once: a standing G1 whole-body tick in double and partial support (with and without the task priority,
    and on DAQP, the fallback:
the one-call tick and the step-by-step kernels), a hull, and LWL2's encoder and k-NN."""
    from dataclasses import replace

    from engine.constants import SIDES
    from engine.control.controller import RobotState
    from engine.control.wbc.controller import TaskSpaceInverseDynamics
    from engine.geometry.polygon import convex_hull_2d
    from engine.robot.model import load_robot

    robot = load_robot("g1")
    state = RobotState(0.0, robot.q_standing.copy(), np.zeros(robot.pin_model.nv))
    plain = TaskSpaceInverseDynamics(robot)
    # and with the task priority on (WbcGains.priority_slack_mps2: its two kernels, engine/control/wbc/priority.py)
    prioritised = TaskSpaceInverseDynamics(robot, gains=replace(plain.gains, priority_slack_mps2=0.01))
    # and DAQP, the active set's fallback (its dense form is written by the compiled fill_daqp)
    daqp = TaskSpaceInverseDynamics(robot, qp_backend="daqp")
    for wbc in (plain, prioritised, daqp):
        wbc.reset(state)
        ref = wbc.hold_reference(robot.q_standing)
        for contact in (np.ones((len(SIDES), 4), dtype=bool), np.eye(len(SIDES), 4, dtype=bool)):
            ref.contact = contact
            wbc.compute(state, ref)
            if not wbc.diagnostics.ok:
                raise RuntimeError(f"kernel warm-up: {wbc.diagnostics.status}: {wbc.diagnostics.message}")
    convex_hull_2d(np.random.default_rng(0).random((8, 2)))
    _warm_up_reference(len(plain.upper_v_indices))
    _warm_up_planner()
    _warm_up_lwl2()


def _warm_up_reference(n_upper: int) -> None:
    """The whole-body reference between planner ticks (:func:`engine.control.reference_kernels.interpolate_reference`,
    and :func:`~engine.control.reference_kernels.interpolate_references` for all of them) on C-contiguous float
    arrays, as the walking controller passes them."""
    from engine.control.reference_kernels import interpolate_reference, interpolate_references

    eye = np.eye(3)
    interpolate_reference(0.002, 0.05, np.array([0.0, 0.1, 0.3]), np.zeros((3, 2)), np.zeros((3, 2)), np.zeros((3, 2)),
                          3.5, np.zeros((2, 3)), np.zeros((2, 3)), np.stack([eye, eye]), np.ones((2, 3)), eye.copy(),
                          np.ones(3), np.zeros(n_upper), np.zeros(n_upper))
    n = 4
    interpolate_references(0.002, 0.05, np.array([0.0, 0.1, 0.3]), np.zeros((3, 2)), np.zeros((3, 2)), np.zeros((3, 2)),
                           3.5, np.zeros((2, 3)), np.zeros((2, 3)), np.stack([eye, eye]), np.ones((2, 3)), eye.copy(),
                           np.ones(3), np.zeros(n_upper), np.zeros(n_upper), np.empty((n, 3, 2)), np.empty((n, 2, 3)),
                           np.empty((n, 2, 3, 3)), np.empty((n, 3, 3)), np.empty(n, dtype=np.bool_),
                           np.empty((n, n_upper)))


def _warm_up_planner() -> None:
    """The gait planner's and the CoM MPC's kernels on the argument types they pass (``ComMpc.solve`` compiles the
    one-call plan, :func:`engine.control.mpc.active_set_kernel.plan_window`, and what it calls, among them the one-call
    solve :func:`~engine.control.mpc.active_set_kernel.solve_window`)."""
    from engine.robot.model import load_robot
    from engine.gait.footsteps import Foothold
    from engine.gait.planner import PATH_TABLE_STEP_S
    from engine.gait.planner_kernels import command_ramp_pieces, path_table_poses, preview_polygons, support_hull

    support_hull((Foothold(0.0, 0.1, 0.0), Foothold(0.1, -0.1, 0.1)), 0.2, 0.08, (None, "heel"), 0.02)
    preview_polygons(np.zeros((2, 2, 3)), np.array([[True, True], [True, False]]), np.zeros((2, 2), dtype=np.int64),
                     0.2, 0.08, 0.01, 0.02)
    _, th, dx, dy = command_ramp_pieces(np.zeros(3), np.array([0.3, 0.0, 0.2]), np.ones(3), PATH_TABLE_STEP_S, 61)
    path_table_poses(0.0, 0.0, 0.0, th, dx, dy)
    from engine.gait.offline_plan import planner_for
    from engine.gait.style import StyleContext, load_style, styles_dir

    planner = planner_for(load_robot("g1"), load_style(styles_dir("g1") / "neutral.json"), StyleContext.for_robot("g1"))
    planner.step(0.008, np.array([0.2, 0.0, 0.0]))  # the reference in one call (evaluate_reference_into), the preview
    planner.nominal_target("left")  # the upcoming foothold (upcoming_foothold) while the command holds
    from engine.gait.planner import PlannerFeedback

    planner.step(0.008, np.array([0.2, 0.0, 0.0]), PlannerFeedback(  # the preview on a (read-only) path table
        command_goal=np.array([0.3, 0.0, 0.1]), command_rate_limits=np.ones(3)))
    planner.nominal_target("right")  # ... and on the path table
    from engine.control.mpc import ComMpc, SupportInterval

    left = np.array([[-0.1, 0.06], [-0.1, 0.14], [0.1, 0.14], [0.1, 0.06]])[::-1]  # clockwise: either orientation
    right = left - [0.0, 0.2]
    both = np.array([[-0.1, -0.14], [0.1, -0.14], [0.1, 0.14], [-0.1, 0.14]])
    supports = [SupportInterval(0.0, 0.2, both), SupportInterval(0.2, 0.6, left), SupportInterval(0.6, 0.7, both),
                SupportInterval(0.7, 2.5, right)]
    mpc = ComMpc()
    for t_s in (0.0, 0.008):  # the second call matches the first one's active rows (warm start)
        plan = mpc.solve(t_s, np.zeros(2), np.array([0.0, 0.1]), np.zeros(2), 0.6, supports)
    if not plan.ok:
        raise RuntimeError(f"kernel warm-up: CoM MPC {plan.status}: {plan.message}")
    # and its step-by-step path (what a walk takes when the one-call plan declines: the problem build, the support
    # geometry, the compiled solve on the built problem): without it the first decline mid-walk loaded those kernels
    # then, a 0.1-0.15 s stall of the live simulation (seen in `studio bench stack`'s G1 sweep)
    stepwise = ComMpc()
    stepwise._solve_window = lambda *_, **__: None  # type: ignore[method-assign]
    plan = stepwise.solve(0.0, np.zeros(2), np.array([0.0, 0.1]), np.zeros(2), 0.6, supports)
    if not plan.ok:
        raise RuntimeError(f"kernel warm-up: CoM MPC step by step {plan.status}: {plan.message}")


def _warm_up_lwl2() -> None:
    """LWL2's run-time kernels (the encoder's forward, the latent k-NN scan) on small arrays of the dtypes and
    layouts the retargeter passes, and training's LA-DPP batch loop."""
    from engine.retarget.humanoid_arm.la_dpp import la_dpp_indices
    from engine.retarget.humanoid_arm.lwr import nearest_k
    from engine.retarget.humanoid_arm.wae import _mlp_forward

    rng = np.random.default_rng(0)
    la_dpp_indices(rng.random((16, 3)), 4, rng)
    latents = rng.random((16, 4))
    k, m = 3, 8
    nearest_k(latents, np.ascontiguousarray(latents.T, dtype=np.float32), rng.random(4), k, m,
              np.empty(16, dtype=np.float32), np.empty(k), np.empty(k, dtype=np.int64))
    hidden, d_in, d_out = 8, 15, 4
    _mlp_forward(rng.random(d_in), rng.random((hidden, d_in)), rng.random(hidden), rng.random((2, hidden, hidden)),
                 rng.random((2, hidden)), rng.random((d_out, hidden)), rng.random(d_out), np.empty((2, hidden)),
                 np.empty(d_out))

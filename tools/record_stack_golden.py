"""Record the control stack's numbers on a short G1 sweep, for tests/test_stack_golden.py.

Run once with the implementation the speed-ups must reproduce (first at commit 924822b, before
any of them; again after the push-recovery changes of the walking controller, which change the
closed loop on purpose)::

    PYTHONPATH=. python tools/record_stack_golden.py tests/data/stack_golden_g1.npz

Closed loop (controller + MuJoCo): every tick's joint command, every planner tick's reference
and CoM plan. Open loop: the inverse dynamics' inputs (state, reference) of a stretch of those
ticks and its outputs, so the whole-body QP can be replayed alone.
"""

from __future__ import annotations

import io
import sys
from dataclasses import fields

import numpy as np

from engine.atomic_io import atomic_write_bytes
from engine.control.wbc import WbcReference
from engine.control.walking_controller import WalkingController
from engine.control.walking_parameters import WalkingParameters
from engine.gait.command_schedule import preset
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot
from engine.sim import Simulation

TICKS = 750  # 1.5 s: stand-up, the first steps of the forward sweep
KEEP_EVERY = 5  # joint commands of every 5th tick are kept
ID_FROM, ID_TO = 500, 600  # ticks whose whole-body QP inputs are kept


def record(robot_name: str = "g1", ticks: int = TICKS) -> dict[str, np.ndarray]:
    robot = load_robot(robot_name)
    style = load_style(styles_dir(robot_name) / "neutral.json")
    schedule = preset("sweep", style.velocities)
    # The recording's parameters (the dataclass defaults, G1's tuning at the time): robot-level tuning in
    # robots/<name>.toml [control.walking] changes the walk, not the numerics this golden guards.
    ctrl = WalkingController(robot, style, params=WalkingParameters())
    sim = Simulation(robot, ctrl)
    out: dict[str, list] = {k: [] for k in ("q_des", "qd_des", "tau_ff", "plan_t", "plan_waypoints", "plan_com",
                                            "ref_foot_pos", "ref_pelvis_z", "ref_upper_q", "id_q", "id_v", "id_qdd",
                                            "id_tau")}
    ref_fields = [f.name for f in fields(WbcReference)]
    refs: dict[str, list] = {f: [] for f in ref_fields}
    compute = ctrl.wbc.compute
    tick = [0]

    def spy(state, reference):  # noqa: ANN001
        cmd = compute(state, reference)
        if ID_FROM <= tick[0] < ID_TO:
            out["id_q"].append(state.q.copy())
            out["id_v"].append(state.v.copy())
            for f in ref_fields:
                value = getattr(reference, f)
                refs[f].append(np.full(6 if f == "external_wrench" else 1, np.nan) if value is None else np.asarray(value, float).copy())
            out["id_qdd"].append(ctrl.wbc.diagnostics.qdd.copy())
            out["id_tau"].append(ctrl.wbc.diagnostics.tau_nm.copy())
        return cmd

    ctrl.wbc.compute = spy
    dt = float(robot.mj_model.opt.timestep)
    last_plan = None
    for k in range(ticks):
        tick[0] = k
        ctrl.set_command(schedule(k * dt))
        sim.step()
        cmd = sim.command
        if k % KEEP_EVERY == 0:
            out["q_des"].append(cmd.q_des.copy())
            out["qd_des"].append(cmd.qd_des.copy())
            out["tau_ff"].append(cmd.tau_ff.copy())
        if ctrl.plan is not last_plan and k % 4 == 0:
            last_plan = ctrl.plan
            wps = np.full((40, 2), np.nan)
            wps[:len(ctrl.plan.waypoints_xy_m)] = ctrl.plan.waypoints_xy_m
            out["plan_t"].append(ctrl.ref.t_s)
            out["plan_waypoints"].append(wps)
            out["plan_com"].append(np.concatenate(ctrl.plan.com_at(ctrl.ref.t_s + 0.1)))
            out["ref_foot_pos"].append(ctrl.ref.foot_pos.copy())
            out["ref_pelvis_z"].append(ctrl.ref.pelvis_z)
            out["ref_upper_q"].append(ctrl.ref.upper_q.copy())
    arrays = {k: np.asarray(v) for k, v in out.items()}
    arrays.update({f"id_ref_{f}": np.asarray(v) for f, v in refs.items()})
    return arrays


if __name__ == "__main__":
    arrays = record()
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(sys.argv[1], buf.getvalue())
    print(sys.argv[1], {k: v.shape for k, v in arrays.items()})

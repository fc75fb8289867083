"""GaitPlanner.evaluate computes the same reference, bit for bit, as the code it replaced (kept here): the blended
channels' values without their rates (BlendedGait.channel_values), both feet's swing test on one phase."""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from engine.control.walking_controller import WalkingController
from engine.gait.command_schedule import preset
from engine.gait.planner import (
    _NO_POS,
    _NO_ROTS,
    CONTACT_TOL_M,
    ROLL_SMOOTHING,
    GaitPlanner,
    GaitReference,
    reference_frames,
)
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot
from engine.sim import Simulation


def evaluate_before(self: GaitPlanner, phi: float) -> GaitReference:
    """GaitPlanner.evaluate before its glue was trimmed (commit bd1817b), as it was."""
    blend = self.blend
    cycle_vals, left_vals, right_vals, *_ = blend.channels(phi)
    t = blend.time_at(phi)
    swinging = (self.in_swing("left", phi), self.in_swing("right", phi))
    left, left_progress = self._foot_params("left", phi, t, blend, left_vals, swinging[0])
    right, right_progress = self._foot_params("right", phi, t, blend, right_vals, swinging[1])
    pelvis_yaw, pelvis_pitch, pelvis_roll = cycle_vals[1:4].tolist()
    params = np.array([float(self.path.yaw), pelvis_yaw, pelvis_pitch, pelvis_roll, self.sole_length_m,
                       self.sole_width_m, ROLL_SMOOTHING, ROLL_SMOOTHING ** 2, *left, *right])
    prev = self._last_pose
    dt = self.t_s - prev["t"] if prev is not None else 0.0
    rots, foot_pos, corners, ang, lin = reference_frames(
        params, self.sole_corners_local, prev["rots"] if prev is not None else _NO_ROTS,
        prev["foot_pos"] if prev is not None else _NO_POS, dt if prev is not None and dt > 0 else 0.0)
    pelvis_rot, foot_rot = rots[0], rots[1:]
    pelvis_z = blend.attribute("pelvis_height_m") + cycle_vals[0]
    upper = cycle_vals[4:].copy()
    # (the soles' rotations are rots[1:], their positions foot_pos: rows left, right)
    self._last_pose = {"t": self.t_s, "pelvis_z": pelvis_z, "rots": rots, "foot_pos": foot_pos, "upper": upper}
    if prev is None or dt <= 0:
        z_rate = 0.0
        upper_qd = np.zeros_like(upper)
    else:
        z_rate = (pelvis_z - prev["pelvis_z"]) / dt
        upper_qd = (upper - prev["upper"]) / dt
    return GaitReference(
        t_s=self.t_s, phase=phi, command=self.command.copy(),
        sample_weights=self.weights.copy(), path_pose=self.path.pose(),
        pelvis_z=pelvis_z, pelvis_z_rate=z_rate, pelvis_rot=pelvis_rot, pelvis_ang_vel=ang[0],
        foot_pos=foot_pos.copy(), foot_rot=foot_rot, foot_lin_vel=lin, foot_ang_vel=ang[1:],
        contact=np.array([not swinging[0], not swinging[1]]),
        corner_contact=corners[:, :, 2] < CONTACT_TOL_M, sole_corners=corners,
        upper_q=upper, upper_qd=upper_qd,
        footholds={"left": self.target["left"] if swinging[0] else self.latched["left"],  # (SIDES' order)
                   "right": self.target["right"] if swinging[1] else self.latched["right"]},
        cycle_s=blend.events_s[3],
        swing_progress=np.array([left_progress, right_progress]),
    )


def _assert_same(a: object, b: object, what: str) -> None:
    """The same type and bits (arrays: shape, dtype and bytes; dicts: keys in order, then each value; floats: their
    8 bytes, so -0.0 is not 0.0; the rest, e.g. Footholds and lists: ==)."""
    assert type(a) is type(b), (what, type(a), type(b))
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray)
        assert a.dtype == b.dtype and a.shape == b.shape, what
        np.testing.assert_array_equal(a, b, err_msg=what)
        assert a.tobytes() == b.tobytes(), what
    elif isinstance(a, (float, np.floating)):
        assert np.float64(a).tobytes() == np.float64(b).tobytes(), (what, a, b)  # type: ignore[arg-type]
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), what
        for key in a:
            _assert_same(a[key], b[key], f"{what}[{key}]")
    else:
        assert a == b, (what, a, b)


def test_evaluate_matches_the_python_it_replaced() -> None:
    """Every planner tick of 4 s of G1's sweep (standing, walking, turning, strafing): the reference and the state
    evaluate leaves for the next tick (_last_pose) equal the replaced code's, field by field."""
    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    schedule = preset("sweep", style.velocities)
    controller = WalkingController(robot, style)
    planner = controller.planner
    evaluate_now = planner.evaluate
    compared, swinging = 0, [0, 0]

    def evaluate_both(phi: float) -> GaitReference:
        nonlocal compared
        prev = planner._last_pose
        now = evaluate_now(phi)
        after_now = planner._last_pose
        planner._last_pose = prev
        before = evaluate_before(planner, phi)
        after_before = planner._last_pose
        for f in fields(GaitReference):
            _assert_same(getattr(now, f.name), getattr(before, f.name), f"{f.name} at t = {planner.t_s}")
        assert after_now is not None and after_before is not None
        _assert_same(after_now, after_before, f"_last_pose at t = {planner.t_s}")
        for i in range(2):
            swinging[i] += not bool(now.contact[i])
        compared += 1
        planner._last_pose = after_now  # the run goes on from the new code's state
        return now

    planner.evaluate = evaluate_both  # type: ignore[method-assign]
    sim = Simulation(robot, controller)
    dt = float(sim.model.opt.timestep)
    for k in range(2000):
        controller.set_command(schedule(k * dt))
        sim.step()
        assert not sim.fallen
    assert compared >= 490 and min(swinging) > 50  # every planner tick; both feet swung and stood

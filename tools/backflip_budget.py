"""Landing budget of the keyframed BackFlip (``tools/make_backflip.py``) on a robot, from its own model: what the
legs must do at touchdown against what their torque limits allow.

    python tools/backflip_budget.py go1 b1

Per robot: mass, centroidal pitch inertia and momenta (MuJoCo subtree momenta of the kinematic clip, 100 Hz,
central differences) at take-off and at the rear-feet touchdown; the largest vertical ground force each foot
can push with at the touchdown posture under the torque box (a linear programme on τ = Jᵀ f with friction
μ = 0.8); then, for α re-timings of the clip (flights re-made ballistic: touchdown vertical speed ∝ α, pitch rate
∝ 1/α, the strokes unchanged), the force the rear legs need to stop the fall within the clip's absorb stroke and
the residual backward pitch before the front feet land (the front feet's upward force, ahead of the centre of
mass, adds backward pitch: only the rear legs can stop it). A rough budget, not a simulation. That first table
counts only vertical forces against the pitch; the second solves a linear programme over both rear feet's 3-D
forces (friction included: horizontal forces below the centre of mass brake the pitch too) and is the one to
believe — a relaxation, so "short" there means torque-infeasible, "FEASIBLE" only "not excluded".
"""

from __future__ import annotations

import sys
from pathlib import Path

import mujoco
import numpy as np
from scipy.optimize import linprog

REPO = Path(__file__).resolve().parents[1]
for p in (str(REPO), str(REPO / "tools")):
    if p not in sys.path:
        sys.path.insert(0, p)

from engine.retarget.quadruped.tmr.deformation import finite_difference_qvel  # noqa: E402
from engine.retarget.quadruped.tmr.keypoints import KeypointSet  # noqa: E402
from engine.retarget.quadruped.tmr.kinematic_clips import keyframed  # noqa: E402
from engine.robot.model import load_robot  # noqa: E402
from make_backflip import keyframes_for  # noqa: E402

MU = 0.8
G = 9.81
ALPHAS = (0.5, 0.71, 1.0, 1.41, 2.0)


def budget(name: str) -> None:
    rb = load_robot(name)
    m, d = rb.mj_model, mujoco.MjData(rb.mj_model)
    dt = 0.01
    mot = keyframed(rb, keyframes_for(rb), fps=1.0 / dt, name="backflip")
    q = mot.qpos
    v = finite_difference_qvel(m, q, dt)
    air = ~mot.contact.any(axis=1)
    k_to = int(np.argmax(air)) - 1
    k_td = k_to + 1 + int(np.argmin(air[k_to + 1:]))
    k_front = k_td + int(np.argmax(mot.contact[k_td:, 0]))
    mass = float(m.body_mass.sum())

    def momenta(k: int):  # noqa: ANN202
        d.qpos[:], d.qvel[:] = q[k], v[k]
        mujoco.mj_forward(m, d)
        mujoco.mj_subtreeVel(m, d)
        return d.subtree_linvel[1].copy(), d.subtree_angmom[1].copy(), d.subtree_com[1].copy()

    lin_to, L_to, _ = momenta(k_to)
    lin_td, L_td, com = momenta(k_td)
    iyy = 0.0
    for b in range(1, m.nbody):
        R = d.ximat[b].reshape(3, 3)
        r = d.xipos[b] - com
        iyy += (R @ np.diag(m.body_inertia[b]) @ R.T)[1, 1] + m.body_mass[b] * (r[0] ** 2 + r[2] ** 2)
    kp = KeypointSet.for_robot(rb)
    pts = kp.positions(d)
    lim = m.actuator_ctrlrange[:, 1]

    def leg_torque_map(leg: int) -> tuple[int, np.ndarray, np.ndarray]:
        """(foot keypoint, Jᵀ of the foot point on the leg's 3 joints, their torque limits)."""
        fi = kp.foot_index[leg]
        jp = np.zeros((3, m.nv))
        mujoco.mj_jac(m, d, jp, None, pts[fi], int(kp.body[fi]))
        joints = kp.joint[4 * leg: 4 * leg + 3]
        JT = jp[:, [int(m.jnt_dofadr[j]) for j in joints]].T
        return fi, JT, lim[[int(np.flatnonzero(m.actuator_trnid[:, 0] == j)[0]) for j in joints]]

    fmax = []
    for leg in range(4):
        _, JT, tl = leg_torque_map(leg)
        A = np.vstack([JT, -JT, [[1, 0, -MU], [-1, 0, -MU], [0, 1, -MU], [0, -1, -MU]]])
        res = linprog([0, 0, -1], A_ub=A, b_ub=np.concatenate([tl, tl, np.zeros(4)]), bounds=[(None, None)] * 3)
        fmax.append(res.x[2] if res.success else float("nan"))
    fmax = np.array(fmax)
    rear = fmax[2] + fmax[3]
    lever = float(np.mean(np.abs(pts[[kp.foot_index[2], kp.foot_index[3]], 0] - com[0])))
    t_front = (k_front - k_td) * dt
    stroke = q[k_td, 2] - q[k_td:, 2].min()
    w = mass * G
    print(f"{name}: mass {mass:.1f} kg ({w:.0f} N), torque limits hip/thigh/knee {lim[:3].round(1).tolist()} N·m, "
          f"centroidal I_yy at touchdown {iyy:.3f} kg·m²")
    print(f"  take-off {k_to * dt:.2f} s: L_y {L_to[1]:+.2f} N·m·s (≈ {L_to[1] / iyy:+.1f} rad/s); flight {(k_td - k_to) * dt:.2f} s")
    print(f"  rear touchdown {k_td * dt:.2f} s: v_z {lin_td[2]:+.2f} m/s, L_y {L_td[1]:+.2f} N·m·s (≈ {L_td[1] / iyy:+.1f} rad/s); "
          f"front feet {t_front:.2f} s later; absorb stroke {stroke:.3f} m; rear feet {lever:.3f} m behind the com")
    print(f"  largest vertical force per foot at that posture FL/FR/RL/RR {fmax.round(0).tolist()} N "
          f"({(fmax / w).round(2).tolist()} body weights); rear pair ≤ {rear:.0f} N")
    for a in ALPHAS:
        f_fall = mass * ((lin_td[2] * a) ** 2 / (2 * stroke) + G)
        f_pitch = abs(L_td[1] / a) / (t_front * a * lever)
        print(f"    α {a:4.2f}: rear legs need ≈ {f_fall + f_pitch:6.0f} N ({f_fall:.0f} stop the fall + {f_pitch:.0f} stop the "
              f"pitch) = {(f_fall + f_pitch) / rear:.1f}× what they can give")
    # the same check with friction: the rear feet's horizontal forces, below the centre of mass, also brake the
    # pitch. A linear programme over both rear feet's forces (friction pyramid μ, torque box through Jᵀ): the
    # largest braking pitch torque while the vertical forces still stop the fall. Every other constraint of a
    # real landing (horizontal momentum, the posture changing over the stroke) is left out, which can only
    # make the landing look easier than it is.
    rows_A, rows_b, r_feet = [], [], []
    for i, leg in enumerate((2, 3)):
        fi, JT, tl = leg_torque_map(leg)
        block = np.vstack([JT, -JT, [[1, 0, -MU], [-1, 0, -MU], [0, 1, -MU], [0, -1, -MU]], [[0, 0, -1]]])
        full = np.zeros((len(block), 6))
        full[:, 3 * i: 3 * i + 3] = block
        rows_A.append(full)
        rows_b.append(np.concatenate([tl, tl, np.zeros(5)]))
        r_feet.append(pts[fi] - com)
    A_feet, b_feet = np.vstack(rows_A), np.concatenate(rows_b)
    # pitch torque about the com: τ_y = r_z f_x − r_x f_z; braking a backward (L_y < 0) rotation needs τ_y > 0
    sign = 1.0 if L_td[1] < 0 else -1.0
    c_tau = np.concatenate([[r[2], 0.0, -r[0]] for r in r_feet]) * sign
    print("  with friction (LP over both rear feet's forces):")
    for a in ALPHAS:
        f_fall = mass * ((lin_td[2] * a) ** 2 / (2 * stroke) + G)
        tau_need = abs(L_td[1] / a) / (t_front * a)
        A = np.vstack([A_feet, [[0, 0, -1, 0, 0, -1]]])
        b = np.concatenate([b_feet, [-f_fall]])
        res = linprog(-c_tau, A_ub=A, b_ub=b, bounds=[(None, None)] * 6)
        if not res.success:
            print(f"    α {a:4.2f}: the rear feet cannot even push the {f_fall:.0f} N that stops the fall")
            continue
        tau_max = float(c_tau @ res.x)
        print(f"    α {a:4.2f}: braking pitch torque needed {tau_need:6.0f} N·m, the rear feet give at most {tau_max:6.0f} N·m "
              f"while pushing {f_fall:.0f} N up: {'FEASIBLE' if tau_max >= tau_need else f'{tau_need / max(tau_max, 1e-9):.1f}× short'}")


if __name__ == "__main__":
    for robot in sys.argv[1:] or ["go1", "b1"]:
        budget(robot)

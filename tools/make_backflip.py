"""Keyframed BackFlip (STMR §VIII-F): twelve kinematic keyframes of a Unitree Go1 made with the project's own
kinematics (engine.retarget.quadruped.tmr.kinematic_clips.keyframed: PCHIP between keyframes, a ballistic base
in flight, per-leg IK keeping stance feet on their touchdown points), written to motions/go1/backflip.npz.

    python tools/make_backflip.py                 # motions/go1/backflip.npz
    python tools/make_backflip.py --robot b1 --out /tmp/backflip_b1.npz

For another robot the same keyframes are used with heights and horizontal travel scaled by the ratio of the
standing base heights (joint keyframes unchanged): a stand-in for spatial retargeting until SMR does it.
The project made this motion, so it ships.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from engine.retarget.quadruped.tmr.kinematic_clips import keyframed  # noqa: E402
from engine.robot.model import load_robot  # noqa: E402

GO1_STANDING_Z_M = 0.274
TWO_PI = 2.0 * np.pi
ALL, REAR, NONE = (True, True, True, True), (False, False, True, True), (False, False, False, False)

# t_s, x_m, Δz_m (from standing), pitch_rad (about +y: negative lifts the nose, a back flip turns −2π; it lands
# slightly over-rotated so the rear feet touch first), front (thigh, calf),
# rear (thigh, calf), contact (FL, FR, RL, RR) holding until the next keyframe
KEYFRAMES = [
    (0.00, 0.00, 0.00, 0.0, (0.80, -1.85), (0.80, -1.85), ALL),  # stand
    (0.20, 0.00, -0.08, 0.0, (1.15, -2.45), (1.15, -2.45), ALL),  # crouch
    (0.35, -0.01, -0.04, -0.35, (0.70, -1.50), (1.25, -2.40), REAR),  # front legs have pushed and lift, nose rises
    (0.45, -0.03, 0.02, -0.85, (0.40, -1.10), (1.05, -2.00), REAR),  # rear legs drive
    (0.55, -0.06, 0.08, -1.45, (1.40, -2.50), (0.45, -1.05), NONE),  # rear take-off: flight begins
    (0.65, -0.10, 0.16, -2.50, (2.00, -2.70), (1.60, -2.70), NONE),  # tuck
    (0.75, -0.14, 0.19, -3.55, (2.00, -2.70), (1.80, -2.70), NONE),  # upside down, tucked
    (0.85, -0.18, 0.15, -4.95, (1.40, -2.20), (1.20, -2.10), NONE),  # opening
    (0.95, -0.22, 0.05, -TWO_PI - 0.35, (0.90, -1.70), (0.75, -1.55), REAR),  # rear touchdown, over-rotated: nose up
    (1.05, -0.24, -0.02, -TWO_PI, (0.85, -1.75), (0.95, -1.95), ALL),  # front touchdown
    (1.20, -0.24, -0.06, -TWO_PI, (1.05, -2.30), (1.10, -2.30), ALL),  # absorb
    (1.48, -0.24, 0.00, -TWO_PI, (0.80, -1.85), (0.80, -1.85), ALL),  # stand
]


def keyframes_for(robot) -> list[dict]:  # noqa: ANN001
    z0 = float(robot.mj_standing_qpos()[2])
    scale = z0 / GO1_STANDING_Z_M
    return [{"t_s": t, "x_m": x * scale, "z_m": z0 + dz * scale, "pitch_rad": p, "front": f, "rear": r, "contact": c}
            for t, x, dz, p, f, r, c in KEYFRAMES]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="go1")
    parser.add_argument("--fps", type=float, default=50.0)
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    robot = load_robot(args.robot)
    motion = keyframed(robot, keyframes_for(robot), fps=args.fps, name="backflip")
    motion.source = {"clip": "backflip", "made_by": "tools/make_backflip.py", "keyframes": len(KEYFRAMES),
                     "licence": "made by the Motion Studio project"}
    out = Path(args.out) if args.out else REPO / "motions" / args.robot / "backflip.npz"
    motion.save(out)
    airborne = ~motion.contact.any(axis=1)
    print(f"{out}: {motion.frames} frames at {args.fps:g} fps ({motion.duration_s:.2f} s), flight "
          f"{airborne.sum() / args.fps:.2f} s, apex {motion.qpos[:, 2].max():.3f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

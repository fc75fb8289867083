"""The three training sets of §IV-B / §V-C.

- glue (paired): 15-d mocap poses and the robot angles optimisation-based retargeting gives them
  (:class:`ArmIK` on bone directions and hand positions, then made collision-free); only pairs the fixer
  frees are kept;
- robot domain: glue robot poses whose randomly chosen joints (1 to 3) are perturbed uniformly within their
  limits, kept when the capsules say collision-free (the paper collects 200 k; ``robot_size`` here);
- mocap domain: every frame of the training BVH clips plus random poses of the synthetic human model.

Only licence-allowed clips (:mod:`sources`: CMU) are used; Bandai Namco is for evaluation only.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from engine.retarget.humanoid_arm import sources
from engine.retarget.humanoid_arm.capsules import CapsuleModel
from engine.retarget.humanoid_arm.ik import ArmIK
from engine.retarget.humanoid_arm.pose15 import HumanModelSource, pose15_from_bvh
from engine.retarget.importers.bvh import load_bvh

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class DatasetSizes:
    glue_clip_stride: int = 3  # every n-th frame of the training clips goes into the glue set
    glue_synthetic: int = 300  # synthetic human poses retargeted into the glue set
    robot: int = 20_000
    mocap_synthetic: int = 5_000
    robot_glue: int = 0  # robot-domain poses paired with their own 15-d pose (the robot as a mocap skeleton)

    @classmethod
    def quick(cls) -> "DatasetSizes":
        return cls(glue_clip_stride=12, glue_synthetic=30, robot=1_500, mocap_synthetic=600)


@dataclass
class ArmDatasets:
    glue_mocap: np.ndarray  # (G, 15)
    glue_robot: np.ndarray  # (G, n)
    robot: np.ndarray  # (R, n) collision-free robot poses (also the LWR table at run time)
    mocap: np.ndarray  # (M, 15)
    info: dict = field(default_factory=dict)

    def sizes(self) -> dict[str, int]:
        return {"glue": len(self.glue_mocap), "robot": len(self.robot), "mocap": len(self.mocap)}


def clip_poses(paths: list[Path]) -> np.ndarray:
    return np.concatenate([pose15_from_bvh(load_bvh(p)) for p in paths]) if paths else np.zeros((0, 15))


def perturbed_robot_poses(cm: CapsuleModel, seeds: np.ndarray, n: int, rng: np.random.Generator,
                          progress: Progress | None = None) -> np.ndarray:
    """``n`` collision-free poses: a random seed pose with 1–3 random joints redrawn within their limits."""
    ub = cm.ub
    out = np.empty((n, ub.n))
    got = tries = 0
    while got < n:
        x = seeds[rng.integers(len(seeds))].copy()
        joints = rng.choice(ub.n, size=rng.integers(1, 4), replace=False)
        x[joints] = rng.uniform(ub.lower[joints], ub.upper[joints])
        tries += 1
        if cm.is_free(x):
            out[got] = x
            got += 1
            if progress is not None and got % 500 == 0:
                progress("robot poses", got, n)
        if tries > 50 * n + 1000:
            raise RuntimeError(f"only {got} of {n} perturbed poses were collision-free after {tries} tries")
    return out


def build_datasets(robot: str, sizes: DatasetSizes = DatasetSizes(), seed: int = 0,
                   progress: Progress | None = None, cm: CapsuleModel | None = None) -> ArmDatasets:
    from engine.retarget.humanoid_arm.upper_body import UpperBody

    rng = np.random.default_rng(seed)
    cm = cm or CapsuleModel(UpperBody(robot))
    ub = cm.ub
    ik = ArmIK(ub, cm)
    clips = sources.train_clips()
    clip = clip_poses(clips)
    human = HumanModelSource()

    # glue: training-clip frames (warm-started along the clip) + synthetic human poses
    glue_in = [clip[:: sizes.glue_clip_stride]]
    glue_in.append(human.sample(sizes.glue_synthetic, rng))
    glue_mocap, glue_robot = [], []
    total = sum(len(g) for g in glue_in)
    done = 0
    for part_index, part in enumerate(glue_in):
        x = None
        for p in part:
            y, ok = ik.solve(p, x if part_index == 0 else None)
            done += 1
            if ok:
                glue_mocap.append(p)
                glue_robot.append(y)
                x = y
            if progress is not None and done % 25 == 0:
                progress("glue (IK + fixer)", done, total)
    glue_mocap_a, glue_robot_a = np.array(glue_mocap), np.array(glue_robot)

    robot_set = perturbed_robot_poses(cm, np.concatenate([glue_robot_a, ub.neutral()[None]]), sizes.robot, rng, progress)
    robot_set = np.concatenate([glue_robot_a, robot_set])
    if sizes.robot_glue:
        from engine.retarget.humanoid_arm.pose15 import pose15_from_robot

        pick = rng.choice(len(robot_set), size=min(sizes.robot_glue, len(robot_set)), replace=False)
        glue_mocap_a = np.concatenate([glue_mocap_a, [pose15_from_robot(ub, x) for x in robot_set[pick]]])
        glue_robot_a = np.concatenate([glue_robot_a, robot_set[pick]])
    mocap_set = np.concatenate([clip, human.sample(sizes.mocap_synthetic, rng)])
    info = {"training_clips": [p.name for p in clips], "sizes": asdict(sizes), "seed": seed,
            "glue_dropped_not_freed": total - len(glue_mocap), "licence": sources.TRAINING_LICENCE}
    return ArmDatasets(glue_mocap_a, glue_robot_a, robot_set, mocap_set, info)


__all__ = ["DatasetSizes", "ArmDatasets", "build_datasets", "perturbed_robot_poses", "clip_poses"]

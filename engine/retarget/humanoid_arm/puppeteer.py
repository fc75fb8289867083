"""The run-time API of LWL2: load a trained robot, feed 15-d poses (or BVH frames / datagrams), get
collision-free upper-body joint targets with collision-free transitions.

    arms = ArmRetargeter.load("g1")
    step = arms.retarget(pose15)           # one control period
    step.targets                            # {joint name: angle (rad)} for the whole-body controller
    arms.reset()                            # forget the current pose (a new clip)

Per call: encode (mocap WAE encoder) → LWR with k = 3 → 1 (:mod:`lwr`) → refinement (below) → if the
straight interpolation from the previous output to the new pose collides, one step along the BFS path of
the transition graph (:mod:`graph`; entered at the nearest node the straight move reaches), or hold the previous
pose when the graph offers nothing collision-free.

Refinement (``refine_iters``, default :data:`REFINE_ITERS`; 0 = the paper's LWL2 unchanged): a few damped
Gauss–Newton steps of the optimisation-based objective (:meth:`ik.ArmIK.gauss_newton`: bone directions and hand
positions) started from LWR's k_max blend and stopped early once the largest joint step is below
:data:`REFINE_TOLERANCE_RAD`, then the capsule fixer (§III). The LWR table is only as dense as its ~20 k poses
in a 10–11-D joint space: its best entry is ~80 mm from a held-out target (the paper reports 79–140 mm), so
the learned map gives the basin and the local steps the last centimetres. Only the refined pose is checked
for collisions; when the fixer cannot free it, LWR's k → 1 fallback runs (feasible by construction, k = 1 at
worst), so every output stays collision-free. The straight move from the previous output is checked at the
poses in between (the target's own check is the fixer's or LWR's).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.retarget.humanoid_arm.capsules import CapsuleModel
from engine.retarget.humanoid_arm.graph import TransitionGraph
from engine.retarget.humanoid_arm.ik import ArmIK
from engine.retarget.humanoid_arm.lwr import LatentLWR
from engine.retarget.humanoid_arm.metadata import check_metadata, weights_path
from engine.retarget.humanoid_arm.pose15 import check_pose15
from engine.retarget.humanoid_arm.upper_body import UpperBody

REFINE_ITERS = 3
REFINE_TOLERANCE_RAD = 1e-3  # the refinement stops once its largest joint step is below this
# per-call profile (RetargetStep.stages_s): check + encode, k-NN, refinement (blend + Gauss–Newton), the capsule
# fixer, LWR's k → 1 checks (only when the fixer failed or without refinement), the transition check / graph step
STAGES = ("encode", "knn", "refine", "fix", "lwr_checks", "transition")


@dataclass
class RetargetStep:
    x: np.ndarray  # driven joint angles (rad), collision-free
    k: int  # LWR's k: the k_max blend that started an accepted refinement, else the feasible k (3..1)
    lwr_x: np.ndarray  # that LWR pose (before refinement and the transition logic)
    transition: str  # "direct", "graph" (one BFS step) or "hold"
    inference_s: float
    refined: bool = False  # the refinement's pose was used (else the LWR pose)
    joint_names: list[str] = field(default_factory=list)
    stages_s: dict[str, float] = field(default_factory=dict)  # where the time went (see :data:`STAGES`)

    @property
    def targets(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.joint_names, self.x)}


class ArmRetargeter:
    def __init__(self, ub: UpperBody, capsules: CapsuleModel, model, robot_poses: np.ndarray,
                 graph: TransitionGraph | None, meta: dict, k_max: int = 3, feed_forward=None,
                 refine_iters: int = REFINE_ITERS, clearance_m: float = 0.0,
                 refine_tolerance_rad: float = REFINE_TOLERANCE_RAD):
        self.ub, self.capsules, self.model, self.meta = ub, capsules, model, meta
        self.robot_poses = robot_poses
        # clearance_m > 0 (live puppeteering): blended and refined poses keep this distance between capsules, so
        # the physical arm's tracking lag does not turn a grazing target into a contact (k = 1 stays a look-up)
        self.clearance_m = float(clearance_m)
        self.lwr = LatentLWR(model.encode("robot", robot_poses), robot_poses,
                             lambda x: capsules.is_free(x, self.clearance_m), k_max)
        self.encode_mocap = model.numpy_encoder("mocap")  # run-time path: numpy, no torch call per frame
        self.refine_iters = int(refine_iters)
        self.refine_tolerance_rad = float(refine_tolerance_rad)
        self.ik = ArmIK(ub, capsules)
        self.graph = graph
        self.feed_forward = feed_forward
        self.current: np.ndarray | None = None
        self.graph_fallbacks = 0
        self.holds = 0
        # warm up torch and the k-d tree so the first live frame is not the slowest
        from engine.retarget.humanoid_arm.pose15 import pose15_from_robot

        self.lwr.query(self.encode_mocap(pose15_from_robot(ub, ub.neutral()))[0])

    @property
    def robot(self) -> str:
        return self.ub.model.name

    @property
    def joint_names(self) -> list[str]:
        return self.ub.joint_names

    @classmethod
    def load(cls, robot: str, path: Path | None = None, capsules: CapsuleModel | None = None,
             refine_iters: int = REFINE_ITERS, clearance_m: float = 0.0,
             refine_tolerance_rad: float = REFINE_TOLERANCE_RAD) -> "ArmRetargeter":
        """Load trained weights for ``robot``; ValueError (one line) when missing or for another robot."""
        path = Path(path) if path is not None else weights_path(robot)
        if path.suffix in (".json", ".safetensors"):
            path = path.with_suffix("")
        check_metadata(path, robot)  # before importing torch: a wrong file fails fast
        from engine.retarget.humanoid_arm.wae import load_weights

        model, extra, meta = load_weights(path)
        ub = capsules.ub if capsules is not None else UpperBody(robot)
        if list(meta.get("joint_names", [])) != ub.joint_names:
            raise ValueError(f"{path.with_suffix('.json')}: joint_names: expected {ub.joint_names}, got {meta.get('joint_names')}")
        capsules = capsules or CapsuleModel(ub)
        poses = extra["robot_poses"].astype(np.float64)
        graph = None
        if "graph_nodes" in extra:
            node_ids = extra["graph_nodes"].astype(np.int64)
            if len(node_ids) and not 0 <= int(node_ids.min()) <= int(node_ids.max()) < len(poses):
                raise ValueError(f"{path.with_suffix('.safetensors')}: data.graph_nodes: expected indices into the "
                                 f"{len(poses)} robot poses, got up to {int(node_ids.max())}")
            sampled = poses[node_ids]
            bridges = extra.get("graph_bridge_poses", np.zeros((0, ub.n))).astype(np.float64).reshape(-1, ub.n)
            try:
                graph = TransitionGraph(np.concatenate([sampled, bridges]), extra["graph_indptr"].astype(np.int64),
                                        extra["graph_indices"].astype(np.int64), sampled=len(sampled))
            except ValueError as exc:  # the graph arrays disagree (e.g. bridges counted, their poses missing)
                raise ValueError(f"{path.with_suffix('.safetensors')}: data.graph_indptr: {exc}") from None
        ff = None
        if meta.get("feed_forward"):
            from engine.retarget.humanoid_arm.feed_forward import load_feed_forward

            ff = load_feed_forward(path)
        return cls(ub, capsules, model, poses, graph, meta, feed_forward=ff, refine_iters=refine_iters,
                   clearance_m=clearance_m, refine_tolerance_rad=refine_tolerance_rad)

    def reset(self, x: np.ndarray | None = None) -> None:
        self.current = None if x is None else np.asarray(x, dtype=float).copy()

    def retarget(self, pose15: np.ndarray) -> RetargetStep:
        """One control period: collision-free joint targets for a 15-d pose (ValueError on a bad pose)."""
        clock = time.perf_counter
        t0 = clock()
        p = check_pose15(np.asarray(pose15, dtype=float).ravel(), "pose15")
        z = self.encode_mocap(p)[0]
        t_encode = clock()
        neighbours = self.lwr.neighbours(z)
        t_knn = t_refine = t_fix = clock()
        refined = False
        if self.refine_iters > 0:
            # the k_max blend starts the refinement whether or not it collides: only the refined pose is checked
            # (LWR's k → 1 checks run only when the fixer cannot free it)
            start = self.lwr.blend(*neighbours, self.lwr.k_max)
            y = self.ik.gauss_newton(p, start, self.refine_iters, self.refine_tolerance_rad)
            t_refine = clock()
            y, free = self.capsules.fix(y, clearance_m=self.clearance_m)
            t_fix = clock()
            if free:
                target, lwr_x, k, refined = y, start, self.lwr.k_max, True
        if not refined:
            res = self.lwr.query(z, neighbours)
            target, lwr_x, k = res.x, res.x, res.k
        t_lwr = clock()
        transition = "direct"
        # the target itself is collision-free (LWR's check or the fixer's): only the poses in between are checked
        if self.current is None or self.capsules.interpolation_free(self.current, target, end_free=True):
            out = target
        else:
            out, transition = self._graph_step(target)
        self.current = out
        t_end = clock()
        stages = dict(zip(STAGES, (t_encode - t0, t_knn - t_encode, t_refine - t_knn, t_fix - t_refine, t_lwr - t_fix,
                                   t_end - t_lwr)))
        return RetargetStep(out.copy(), k, lwr_x, transition, t_end - t0,
                            refined=refined and transition == "direct", joint_names=self.joint_names, stages_s=stages)

    def _graph_step(self, target: np.ndarray) -> tuple[np.ndarray, str]:
        assert self.current is not None
        if self.graph is not None:
            # entered at the nearest node the straight move reaches (the paper's nearest node may be behind a
            # collision: the arm would hold there until the target moves)
            path = self.graph.path(self.current, target, self.capsules.interpolation_free)
            if path is not None:
                # the first node not yet reached, if the move there is collision-free
                for node in path:
                    if np.max(np.abs(node - self.current)) < 1e-9:
                        continue
                    if self.capsules.interpolation_free(self.current, node):
                        self.graph_fallbacks += 1
                        return node.copy(), "graph"
                    break
        self.holds += 1
        return self.current.copy(), "hold"

    def feed_forward_pose(self, pose15: np.ndarray) -> np.ndarray:
        """The glue-only feed-forward baseline's joint angles (no feasibility guarantee)."""
        if self.feed_forward is None:
            raise ValueError("these weights carry no feed-forward baseline")
        return self.ub.clip(self.feed_forward(np.atleast_2d(pose15))[0])


__all__ = ["ArmRetargeter", "RetargetStep", "STAGES", "REFINE_ITERS", "REFINE_TOLERANCE_RAD", "check_metadata", "weights_path"]

"""`studio train-arms`: datasets → shared-latent WAEs (LA-DPP batches) → LWR table → transition graph →
weights (safetensors) + metadata (JSON), plus the glue-only feed-forward baseline.

LA-DPP measures robot poses by their hand and elbow positions in the pelvis frame (the paper uses hand
positions and orientations; our wrists are fixed) and mocap poses by their 15-d vectors.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from engine.retarget.humanoid_arm.capsules import CapsuleModel
from engine.retarget.humanoid_arm.datasets import ArmDatasets, DatasetSizes, build_datasets
from engine.retarget.humanoid_arm.feed_forward import save_feed_forward, train_feed_forward
from engine.retarget.humanoid_arm.graph import TransitionGraph
from engine.retarget.humanoid_arm.la_dpp import la_dpp_indices
from engine.retarget.humanoid_arm.metadata import weights_path
from engine.retarget.humanoid_arm.upper_body import UpperBody
from engine.retarget.humanoid_arm.wae import DomainData, SharedLatentWAE, TrainConfig, save_weights, train_wae

Progress = Callable[[str, int, int, str], None]


@dataclass(frozen=True)
class ArmTrainingPlan:
    sizes: DatasetSizes
    train: TrainConfig
    latent_dim: int = 8
    hidden: int = 128
    graph_nodes: int = 10_000  # the paper's 10 k, LA-DPP-sampled over the whole robot table
    graph_neighbours: int = 10  # collision-free edges each node looks for among the nodes within one period
    # A graph edge must be coverable within this period at the joints' URDF velocity limits. One mocap frame
    # (1/30 s) allows G1 (30–37 rad/s) ~1 rad but TALOS (2.7–5.4 rad/s) 0.1–0.2 rad per joint: among 10 k nodes
    # in 10-D, TALOS's nearest node is then a median 3.7 periods away (no graph). At 0.2 s G1's bound (6–7 rad)
    # exceeds its joint ranges (only collisions limit its edges); TALOS's (0.54–1.08 rad) leaves ~1 % of its
    # 10 k nodes with no node within one period: the bridges join them (graph.py), still one period per edge.
    control_period_s: float = 0.2
    graph_bridge_candidates: int = 20  # nearest outside pairs a component tries for a bridge (0: no bridges)
    ff_iterations: int = 2000

    @classmethod
    def full(cls, robot: str = "g1") -> "ArmTrainingPlan":
        """The plan of the shipped weights (``studio train-arms --robot R`` reproduces them); the same for every
        robot (TALOS trains in about as much CPU time as G1)."""
        return cls(DatasetSizes(), TrainConfig(iterations=3000, la_dpp_chunk=2048))

    @classmethod
    def quick(cls) -> "ArmTrainingPlan":
        return cls(DatasetSizes.quick(), TrainConfig(iterations=200, batch_size=64, la_dpp_chunk=1024),
                   latent_dim=6, hidden=48, graph_nodes=200, graph_neighbours=6, ff_iterations=300)


def robot_features(ub: UpperBody, poses: np.ndarray) -> np.ndarray:
    """(N, 12): both hands and elbows in the pelvis frame (LA-DPP's distance for robot poses)."""
    out = np.empty((len(poses), 12))
    for i, x in enumerate(poses):
        p = ub.points(x)
        out[i] = np.concatenate([p["hand"].ravel(), p["elbow"].ravel()])
    return out


def build_transition_graph(cm: CapsuleModel, poses: np.ndarray, feats: np.ndarray, plan: ArmTrainingPlan,
                           rng: np.random.Generator, progress: Callable[[int, int], None] | None = None
                           ) -> tuple[np.ndarray, TransitionGraph]:
    """LA-DPP-sampled nodes of the robot table (the greedy selection over the whole table, not a random chunk of
    it), their collision-free, one-period edges and the bridges joining the components."""
    ub = cm.ub
    node_idx = np.sort(la_dpp_indices(feats, min(plan.graph_nodes, len(poses)), rng, chunk=len(poses)))
    velocity = np.array(ub.pin_model.velocityLimit)[ub.v_index]
    max_step = np.maximum(velocity * plan.control_period_s, 0.05)
    graph = TransitionGraph.build(poses[node_idx], max_step, cm.interpolation_free, plan.graph_neighbours, progress,
                                  bridge_candidates=plan.graph_bridge_candidates)
    return node_idx, graph


DATASETS_FORMAT = "lwl2-datasets/1"


def save_datasets(path: Path, ds: ArmDatasets, plan: ArmTrainingPlan) -> None:
    """The built training sets (plain arrays, no pickle), keyed by the plan's sizes and seed."""
    import io

    from engine.atomic_io import atomic_write_bytes

    buf = io.BytesIO()
    np.savez(buf, glue_mocap=ds.glue_mocap, glue_robot=ds.glue_robot, robot=ds.robot, mocap=ds.mocap,
             info=np.array(json.dumps(ds.info)), key=np.array(_datasets_key(plan)))
    atomic_write_bytes(path, buf.getvalue())


def load_datasets(path: Path, plan: ArmTrainingPlan) -> ArmDatasets | None:
    """The saved training sets when they were built with this plan's sizes and seed, else None."""
    try:
        with np.load(path, allow_pickle=False) as f:
            if str(f["key"]) != _datasets_key(plan):
                return None
            return ArmDatasets(f["glue_mocap"], f["glue_robot"], f["robot"], f["mocap"], json.loads(str(f["info"])))
    except (OSError, KeyError, ValueError):
        return None


def _datasets_key(plan: ArmTrainingPlan) -> str:
    return json.dumps({"format": DATASETS_FORMAT, "sizes": asdict(plan.sizes), "seed": plan.train.seed}, sort_keys=True)


def default_checkpoint_dir(out: Path) -> Path:
    """Where a run writing ``out`` keeps its resumable state (outside the repository)."""
    import hashlib
    import os

    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "motion-studio" / "train-arms"
    tag = hashlib.sha1(str(Path(out).resolve()).encode()).hexdigest()[:10]
    return cache / f"{Path(out).name}-{tag}"


def train_arms(robot: str, plan: ArmTrainingPlan, out: Path | None = None, progress: Progress | None = None,
               should_stop: Callable[[], bool] | None = None, datasets: ArmDatasets | None = None,
               checkpoint_dir: Path | None = None, resume: bool = False) -> dict:
    """Train and save; returns a summary. KeyboardInterrupt (cancel) leaves no partial weights behind.

    With ``checkpoint_dir`` the built datasets and the WAE's state (every 100 iterations and on cancel) are
    kept there; ``resume`` continues from them (same plan and seed: same weights as an uninterrupted run),
    otherwise they are discarded first. They are deleted once the weights are written."""
    t0 = time.perf_counter()
    say = (lambda stage, i, n, extra="": progress(stage, i, n, extra)) if progress else (lambda *a, **k: None)
    out = out or weights_path(robot)
    ds_file = ckpt_file = None
    if checkpoint_dir is not None:
        checkpoint_dir = Path(checkpoint_dir)
        checkpoint_dir.mkdir(parents=True, exist_ok=True)
        ds_file, ckpt_file = checkpoint_dir / f"{robot}_datasets.npz", checkpoint_dir / f"{robot}_wae_checkpoint.pt"
        if not resume:
            for f in (ds_file, ckpt_file):
                f.unlink(missing_ok=True)
    ub = UpperBody(robot)
    cm = CapsuleModel(ub)
    say("capsules", 1, 1, f"{len(cm.capsules)} capsules, {len(cm.pairs)} pairs")
    if datasets is None and ds_file is not None and ds_file.is_file():
        datasets = load_datasets(ds_file, plan)
        if datasets is not None:
            say("datasets (resumed)", 1, 1, f"{ds_file}")
    ds = datasets or build_datasets(robot, plan.sizes, plan.train.seed, lambda s, i, n: say(s, i, n), cm)
    if ds_file is not None and not ds_file.is_file():
        save_datasets(ds_file, ds, plan)
    t_data = time.perf_counter() - t0
    rng = np.random.default_rng(plan.train.seed)
    feats = robot_features(ub, ds.robot)
    model = SharedLatentWAE({"mocap": 15, "robot": ub.n}, plan.latent_dim, plan.hidden, seed=plan.train.seed)
    train_wae(model, {"mocap": DomainData(ds.mocap), "robot": DomainData(ds.robot, feats)},
              {"mocap": ds.glue_mocap, "robot": ds.glue_robot}, plan.train,
              progress=lambda i, n, losses: say("WAE", i, n, f"rec {losses['rec']:.3f} lat {losses['latent']:.3f} "
                                                               f"cro {losses['cross']:.3f}"),
              should_stop=should_stop, checkpoint=ckpt_file)
    t_train = time.perf_counter() - t0 - t_data
    ff = train_feed_forward(ds.glue_mocap, ds.glue_robot, plan.ff_iterations, plan.hidden, plan.train.seed)
    node_idx, graph = build_transition_graph(cm, ds.robot, feats, plan, rng, lambda i, n: say("graph", i, n))
    if should_stop is not None and should_stop():
        raise KeyboardInterrupt
    sizes = graph.component_sizes()
    meta = {
        "format": "lwl2-arms/1", "robot": robot, "joint_names": ub.joint_names,
        "normalisation": {k: dict(zip(("mean", "std"), (a.tolist() for a in model.normalisation_of(k))))
                          for k in ("mocap", "robot")},
        "dataset_sizes": ds.sizes(), "datasets": ds.info, "licence_of_training_data": ds.info["licence"],
        "plan": {"sizes": asdict(plan.sizes), "train": asdict(plan.train), "latent_dim": plan.latent_dim,
                 "hidden": plan.hidden, "graph_nodes": int(len(node_idx)), "graph_neighbours": plan.graph_neighbours,
                 "control_period_s": plan.control_period_s, "graph_bridge_candidates": plan.graph_bridge_candidates},
        "graph": {"nodes": int(len(graph.nodes)), "sampled_nodes": int(len(node_idx)), "bridge_nodes": int(len(graph.bridges)),
                  "edges": int(len(graph.indices) // 2), "components": len(sizes), "component_sizes": sizes[:10]},
        "capsules": [{"name": c.name, "radius_m": round(c.radius, 4), "length_m": round(float(np.linalg.norm(c.b - c.a)), 4)}
                     for c in cm.capsules],
        "feed_forward": True,
        "timing_s": {"datasets": round(t_data, 1), "wae": round(t_train, 1), "total": round(time.perf_counter() - t0, 1)},
    }
    save_weights(model, out, {"robot_poses": ds.robot.astype(np.float64),  # float64: k = 1 must stay exactly collision-free
                              "graph_nodes": node_idx.astype(np.int32),
                              "graph_bridge_poses": graph.bridges.astype(np.float64).reshape(-1, ub.n),
                              "graph_indptr": graph.indptr.astype(np.int64), "graph_indices": graph.indices.astype(np.int32)},
                 meta)
    save_feed_forward(ff, out)
    for leftover in (ds_file, ckpt_file):
        if leftover is not None:
            leftover.unlink(missing_ok=True)
    if checkpoint_dir is not None and not any(checkpoint_dir.iterdir()):
        checkpoint_dir.rmdir()
    return {"weights": str(out.with_suffix(".safetensors")), **{k: meta[k] for k in ("dataset_sizes", "graph", "timing_s")}}


__all__ = ["ArmTrainingPlan", "train_arms", "default_checkpoint_dir", "save_datasets", "load_datasets", "robot_features", "build_transition_graph"]

"""`studio train-arms --quick`, `studio puppet`, `studio stream-bvh` and their one-line errors."""

from __future__ import annotations

import json
import shutil
import socket
from pathlib import Path

import numpy as np
import pytest

from engine.retarget.humanoid_arm import sources
from engine.retarget.humanoid_arm.ik import arm_errors_m
from engine.retarget.humanoid_arm.live import DatagramError, parse_datagram
from engine.retarget.humanoid_arm.pose15 import bvh_points
from engine.retarget.humanoid_arm.puppeteer import STAGES, ArmRetargeter
from engine.retarget.humanoid_arm.wae import SharedLatentWAE
from engine.retarget.importers.bvh import load_bvh
from tests.conftest import run_studio


def _clip(name: str):
    root = sources.shared_dir()
    path = root / "mocap-src/cmu" / name if root else None
    if path is None or not path.is_file():
        pytest.skip("shared mocap clips absent (set MOTION_STUDIO_SHARED)")
    return path


@pytest.fixture(scope="module")
def quick_weights(tmp_path_factory):
    _clip("131_01.bvh")
    out = tmp_path_factory.mktemp("arms") / "g1_lwl2"
    res = run_studio("train-arms", "--robot", "g1", "--quick", "--out", str(out), timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    summary = json.loads(res.stdout)
    assert summary["dataset_sizes"]["robot"] > 1000
    return out


@pytest.fixture(scope="module")
def shipped_g1():
    from engine.retarget.humanoid_arm.metadata import weights_path

    path = weights_path("g1")
    if not path.with_suffix(".json").is_file():
        pytest.skip("no shipped g1 weights")
    return path


@pytest.mark.slow
def test_quick_training_beats_an_untrained_model(quick_weights):
    held_out = _clip("141_16.bvh")
    poses = bvh_points(load_bvh(held_out)).pose15()[::8]
    # refine_iters = 0: the learned map alone (the refinement would polish an untrained model's poses too)
    trained = ArmRetargeter.load("g1", quick_weights, refine_iters=0)
    import torch

    torch.manual_seed(0)  # the untrained baseline's initial weights: the same in every run, whatever ran before
    blank = SharedLatentWAE(trained.model.dims, trained.model.latent_dim, trained.model.hidden)
    blank.load_state_dict({k: v for k, v in trained.model.state_dict().items() if k.startswith(("mean_", "std_"))},
                          strict=False)
    untrained = ArmRetargeter(trained.ub, trained.capsules, blank, trained.robot_poses, trained.graph, trained.meta,
                              refine_iters=0)
    errors = {}
    for name, arms in (("trained", trained), ("untrained", untrained)):
        hand = []
        for p in poses:
            step = arms.retarget(p)
            assert arms.capsules.is_free(step.x)
            hand.append(arm_errors_m(arms.ub, step.x, p)[0])
        errors[name] = float(np.mean(hand))
    assert errors["trained"] < 0.8 * errors["untrained"], errors


@pytest.mark.slow  # a whole clip retargeted in a `studio puppet` process
def test_puppet_writes_a_collision_free_motion(shipped_g1, tmp_path):
    out = tmp_path / "wave.npz"
    res = run_studio("puppet", "--robot", "g1", "--bvh", str(_clip("141_16.bvh")), "--out", str(out),
                     "--weights", str(shipped_g1), "--json")
    assert res.returncode == 0, res.stderr
    summary = json.loads(res.stdout)
    assert summary["collision_free_fraction"] == 1.0
    for key in ("frames", "hand_error_mm", "elbow_error_mm", "inference_us", "graph_fallbacks"):
        assert key in summary
    with np.load(out, allow_pickle=False) as z:
        assert z["q"].shape == (summary["frames"], len(z["joint_names"]))
        assert bool(np.all(z["collision_free"]))


def test_puppet_bad_input_is_one_line_and_writes_nothing(shipped_g1, tmp_path):
    src = _clip("141_16.bvh").read_text()
    truncated = tmp_path / "truncated.bvh"
    truncated.write_text(src[: int(len(src) * 0.6)])
    no_arms = tmp_path / "legs.bvh"
    no_arms.write_text(src.replace("LeftForeArm", "LeftShin").replace("RightForeArm", "RightShin"))
    # damaged weight files: the networks' tensors cut short; the feed-forward baseline missing or cut short
    damaged = {}
    for name, cut in (("cut", ".safetensors"), ("no_ff", None), ("cut_ff", "_ff.safetensors")):
        folder = tmp_path / name
        folder.mkdir()
        for suffix in (".json", ".safetensors", "_ff.safetensors"):
            src_file, dst_file = Path(f"{shipped_g1}{suffix}"), folder / f"g1_lwl2{suffix}"
            if name == "no_ff" and suffix == "_ff.safetensors":
                continue
            if suffix == cut:
                dst_file.write_bytes(src_file.read_bytes()[:3000])
            else:
                shutil.copyfile(src_file, dst_file)
        damaged[name] = str(folder / "g1_lwl2")
    out = tmp_path / "x.npz"
    cases = [
        (["--robot", "g1", "--bvh", str(truncated), "--weights", str(shipped_g1)], "truncated"),
        (["--robot", "g1", "--bvh", str(_clip("141_16.bvh")), "--weights", damaged["cut"]], "cannot load weights"),
        (["--robot", "g1", "--bvh", str(_clip("141_16.bvh")), "--weights", damaged["no_ff"]], "feed-forward"),
        (["--robot", "g1", "--bvh", str(_clip("141_16.bvh")), "--weights", damaged["cut_ff"]], "feed-forward"),
        (["--robot", "g1", "--bvh", str(no_arms), "--weights", str(shipped_g1)], "no arm joints"),
        (["--robot", "talos", "--bvh", str(_clip("141_16.bvh")), "--weights", str(shipped_g1)], "expected weights for talos"),
        (["--robot", "g1", "--bvh", str(tmp_path / "missing.bvh")], "no such"),
    ]
    for args, expected in cases:
        res = run_studio("puppet", *args, "--out", str(out))
        assert res.returncode == 2, (args, res.stderr)
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and expected in lines[0], lines
        assert not out.exists()


def test_bench_arms_reads_the_weights_dir_it_is_given(tmp_path, shipped_g1):
    """``studio bench arms --weights-dir DIR`` looks for ``<robot>_lwl2`` there, not in the shipped folder: a robot
    without weights there, or with another robot's, is one note row naming the file (nothing measured); a folder
    that does not exist is one line and exit 2."""
    _clip("141_16.bvh")
    res = run_studio("bench", "arms", "--weights-dir", str(tmp_path / "missing"))
    assert res.returncode == 2 and res.stderr.strip().count("\n") == 0 and "--weights-dir" in res.stderr, res.stderr
    res = run_studio("bench", "arms", "--weights-dir", "")  # not "the shipped weights" in disguise
    assert res.returncode == 2 and "--weights-dir" in res.stderr, res.stderr
    for suffix in (".json", ".safetensors", "_ff.safetensors"):
        shutil.copyfile(f"{shipped_g1}{suffix}", tmp_path / f"talos_lwl2{suffix}")
    res = run_studio("bench", "arms", "--json", "--weights-dir", str(tmp_path))
    assert res.returncode == 0, res.stderr[-2000:]
    rows = json.loads(res.stdout)["rows"]
    notes = {row["robot"]: row["note"] for row in rows}
    assert set(notes) == {"g1", "talos"} and len(rows) == 2, rows
    assert str(tmp_path / "g1_lwl2") in notes["g1"] and "no trained weights" in notes["g1"]
    assert "expected weights for talos" in notes["talos"] and str(tmp_path) in notes["talos"]


def test_stream_bvh_sends_one_parseable_datagram_per_frame():
    clip = _clip("141_16.bvh")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))  # the OS picks a free UDP port: no race with a parallel test (pytest -n)
        port = sock.getsockname()[1]
        sock.settimeout(60)
        res = run_studio("stream-bvh", str(clip), "--to", f"udp://127.0.0.1:{port}", "--fps", "60", "--max-frames", "6")
        assert res.returncode == 0, res.stderr
        got = [parse_datagram(sock.recv(65536)) for _ in range(6)]
    expected = bvh_points(load_bvh(clip)).pose15()[::2]
    for i, (frame, pose) in enumerate(got):
        assert frame == 2 * i
        np.testing.assert_allclose(pose, expected[i], atol=1e-5)


@pytest.mark.parametrize("payload, field", [
    (b"not json", "UTF-8 JSON"),
    (b'{"format": "mocap-joints/1", "joints": {"hips": [0, NaN, 0]}}', "joints.hips"),
    (b'{"format": "mocap-joints/1", "joints": {}}', "joints.hips"),
    (b'{"format": "other"}', "format"),
    (b"[1, 2]", "object"),
])
def test_bad_datagrams_are_named(payload, field):
    with pytest.raises(DatagramError) as err:
        parse_datagram(payload)
    assert field in str(err.value) and "\n" not in str(err.value)


def test_stream_bvh_rejects_a_bad_target():
    res = run_studio("stream-bvh", str(_clip("141_16.bvh")), "--to", "tcp://127.0.0.1:9")
    assert res.returncode == 2 and "udp://HOST:PORT" in res.stderr


def test_shipped_g1_weights_retarget_a_held_out_clip_collision_free():
    from engine.retarget.humanoid_arm.metadata import check_metadata, weights_path

    path = weights_path("g1")
    if not path.with_suffix(".json").is_file():
        pytest.skip("no shipped g1 weights")
    meta = check_metadata(path, "g1")
    assert "131_01.bvh" in meta["datasets"]["training_clips"] and "Bandai" not in meta["licence_of_training_data"]
    arms = ArmRetargeter.load("g1")
    poses = bvh_points(load_bvh(_clip("141_16.bvh"))).pose15()[::4]
    previous = None
    for p in poses:
        step = arms.retarget(p)
        assert arms.capsules.is_free(step.x)
        if previous is not None and step.transition != "hold":
            assert arms.capsules.interpolation_free(previous, step.x)
        previous = step.x


def test_refinement_brings_lwl2_near_ik_and_stays_collision_free(shipped_g1):
    """The shipped run-time path (LWR + refinement + fixer) on the held-out clip: every output collision-free,
    the hand error far below the paper's LWR alone and near per-frame IK with fixing (the issue's goal is
    within 20 %; the bench measures it on every held-out clip)."""
    from engine.retarget.humanoid_arm.ik import ArmIK

    poses = bvh_points(load_bvh(_clip("141_16.bvh"))).pose15()[::8]
    refined = ArmRetargeter.load("g1")
    paper = ArmRetargeter.load("g1", capsules=refined.capsules, refine_iters=0)
    ik = ArmIK(refined.ub, refined.capsules)
    hand = {"refined": [], "paper": [], "ik": []}
    x_ik = None
    for p in poses:
        for name, arms in (("refined", refined), ("paper", paper)):
            step = arms.retarget(p)
            assert arms.capsules.is_free(step.x)
            hand[name].append(arm_errors_m(arms.ub, step.x, p)[0])
            # the per-call profile (bench arms) accounts for the whole call, stage by stage
            assert tuple(step.stages_s) == STAGES and min(step.stages_s.values()) >= 0.0
            assert sum(step.stages_s.values()) == pytest.approx(step.inference_s, rel=1e-6, abs=1e-9)
        x_ik, _ = ik.solve(p, x_ik)
        hand["ik"].append(arm_errors_m(refined.ub, x_ik, p)[0])
    mean = {k: float(np.mean(v)) for k, v in hand.items()}
    assert mean["refined"] < 0.5 * mean["paper"], mean
    assert mean["refined"] < 1.5 * mean["ik"] + 0.005, mean


@pytest.mark.parametrize("robot", ["g1", "talos"])
def test_shipped_transition_graph_is_one_component_of_one_period_collision_free_edges(robot):
    """§IV-C on the shipped weights: 10 k LA-DPP nodes (+ bridges) in one component, so BFS always finds a path;
    every edge within one control period at the URDF velocity limits; the bridge poses and a sample of the
    edges collision-free (the capsules); trained on CMU + synthetic poses only."""
    from engine.retarget.humanoid_arm.metadata import check_metadata, weights_path

    path = weights_path(robot)
    if not path.with_suffix(".json").is_file():
        pytest.skip(f"no shipped {robot} weights")
    meta = check_metadata(path, robot)
    assert meta["datasets"]["training_clips"] == ["131_01.bvh"] and "Bandai" not in meta["licence_of_training_data"]
    arms = ArmRetargeter.load(robot)
    g, ub = arms.graph, arms.ub
    assert g is not None and g.sampled == meta["plan"]["graph_nodes"] == 10_000
    assert g.component_sizes() == [len(g.nodes)] == [meta["graph"]["nodes"]]
    max_step = np.maximum(np.array(ub.pin_model.velocityLimit)[ub.v_index] * meta["plan"]["control_period_s"], 0.05)
    rows = np.repeat(np.arange(len(g.nodes)), np.diff(g.indptr))
    assert np.all(np.abs(g.nodes[rows] - g.nodes[g.indices]) <= max_step)
    assert all(arms.capsules.is_free(x) for x in g.bridges)
    bridge_edges = np.flatnonzero((rows >= g.sampled) | (g.indices >= g.sampled))  # every edge touching a bridge
    assert (len(bridge_edges) > 0) == (len(g.bridges) > 0)
    pick = np.concatenate([bridge_edges, np.random.default_rng(0).choice(len(rows), 100, replace=False)])
    assert all(arms.capsules.interpolation_free(g.nodes[rows[e]], g.nodes[g.indices[e]]) for e in pick)

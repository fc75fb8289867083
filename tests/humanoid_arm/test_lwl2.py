"""LWL2's learning parts: LA-DPP (the §V-A imbalance experiment), LWR's k = 1 look-up, BFS transitions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.retarget.humanoid_arm.graph import TransitionGraph, bfs_path
from engine.retarget.humanoid_arm.la_dpp import la_dpp_indices
from engine.retarget.humanoid_arm.lwr import LatentLWR
from engine.retarget.humanoid_arm.wae import DomainData, SharedLatentWAE, TrainConfig, train_wae


def test_la_dpp_spreads_a_crammed_set():
    rng = np.random.default_rng(0)
    uniform = rng.uniform(0, 5, (1000, 2))
    crammed = rng.uniform(1.0, 1.5, (1000, 2))
    data = np.concatenate([uniform, crammed])
    idx = la_dpp_indices(data, 100, rng)
    assert len(set(idx.tolist())) == 100
    inside = np.mean(np.all((data[idx] >= 1.0) & (data[idx] <= 1.5), axis=1))
    assert inside < 0.1  # random sampling puts ~50 % there
    # divide and conquer: a chunk smaller than the set still returns distinct valid indices
    idx2 = la_dpp_indices(data, 50, rng, chunk=500)
    assert len(set(idx2.tolist())) == 50 and idx2.max() < len(data)


@pytest.mark.slow  # two 400-iteration WAE trainings (an experiment, §V-A)
def test_la_dpp_imbalance_experiment_reconstructs_the_domain_better():
    """§V-A / Fig. 2: a 2-D uniform domain with half its points crammed into a small square. A WAE trained
    on random mini-batches spends its capacity on the square; with LA-DPP batches it reconstructs the
    whole domain (uniform test points) with a clearly lower error."""
    rng = np.random.default_rng(0)
    n = 2000
    data = np.concatenate([rng.uniform(0, 5, (n // 2, 2)), rng.uniform(1.0, 1.5, (n // 2, 2))])
    test = rng.uniform(0, 5, (1000, 2))
    errors = {}
    for la_dpp in (False, True):
        model = SharedLatentWAE({"x": 2}, latent_dim=2, hidden=32)
        train_wae(model, {"x": DomainData(data, dpp_features=data)}, None,
                  TrainConfig(iterations=400, batch_size=64, la_dpp=la_dpp, seed=1))
        recon = model.decode("x", model.encode("x", test))
        errors[la_dpp] = float(np.mean(np.linalg.norm(recon - test, axis=1)))
    assert errors[True] < 0.6 * errors[False], errors


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10_000))
def test_lwr_k1_returns_exactly_a_stored_pose(seed):
    rng = np.random.default_rng(seed)
    latents = rng.standard_normal((50, 3))
    poses = rng.uniform(-1, 1, (50, 4))
    lwr = LatentLWR(latents, poses, is_free=lambda x: False, k_max=3)  # nothing blended is feasible
    z = rng.standard_normal(3)
    res = lwr.query(z)
    nearest = int(np.argmin(np.linalg.norm(latents - z, axis=1)))
    assert res.k == 1
    assert np.array_equal(res.x, poses[nearest])


def test_lwr_uses_the_largest_feasible_k():
    latents = np.array([[0.0], [1.0], [2.0], [10.0]])
    poses = np.array([[0.0], [1.0], [2.0], [10.0]])
    assert LatentLWR(latents, poses, lambda x: True).query([0.9]).k == 3
    # k = 3 blends 1, 0 and 2 to ≈ 0.95 (refused), k = 2 blends 1 and 0 to ≈ 0.62 (accepted)
    res = LatentLWR(latents, poses, lambda x: x[0] < 0.8).query([0.9])
    assert res.k == 2 and 0.4 < res.x[0] < 0.8


def _csr(n, edges):
    adj = [[] for _ in range(n)]
    for a, b in edges:
        adj[a].append(b)
        adj[b].append(a)
    indptr = np.zeros(n + 1, dtype=np.int64)
    indptr[1:] = np.cumsum([len(a) for a in adj])
    return indptr, np.array([j for a in adj for j in sorted(a)], dtype=np.int64)


def test_bfs_finds_the_shortest_path_on_a_small_graph():
    # 0-1-2-3-4 chain plus a shortcut 0-5-4 and a disconnected 6
    indptr, indices = _csr(7, [(0, 1), (1, 2), (2, 3), (3, 4), (0, 5), (5, 4)])
    assert bfs_path(indptr, indices, 0, 4) == [0, 5, 4]
    assert bfs_path(indptr, indices, 1, 3) == [1, 2, 3]
    assert bfs_path(indptr, indices, 2, 2) == [2]
    assert bfs_path(indptr, indices, 0, 6) is None


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000))
def test_bfs_path_length_equals_breadth_first_distance(seed):
    rng = np.random.default_rng(seed)
    n = 12
    edges = {tuple(sorted(e)) for e in rng.integers(0, n, (18, 2)).tolist() if e[0] != e[1]}
    indptr, indices = _csr(n, edges)
    dist = np.full((n, n), np.inf)
    np.fill_diagonal(dist, 0)
    for a, b in edges:
        dist[a, b] = dist[b, a] = 1
    for k in range(n):  # Floyd–Warshall as the reference
        dist = np.minimum(dist, dist[:, [k]] + dist[[k], :])
    for s in range(n):
        for g in range(n):
            path = bfs_path(indptr, indices, s, g)
            if np.isinf(dist[s, g]):
                assert path is None
            else:
                assert len(path) - 1 == dist[s, g]
                assert all(b in indices[indptr[a]:indptr[a + 1]] for a, b in zip(path, path[1:]))


def test_transition_graph_edges_respect_step_and_collisions():
    nodes = np.linspace(0, 1, 11)[:, None]
    blocked = lambda a, b: not (min(a[0], b[0]) < 0.55 < max(a[0], b[0]))  # noqa: E731 - a wall at 0.55
    g = TransitionGraph.build(nodes, np.array([0.15]), blocked, neighbours=4)
    for i in range(len(nodes)):
        for j in g.indices[g.indptr[i]:g.indptr[i + 1]]:
            assert abs(nodes[i, 0] - nodes[j, 0]) <= 0.15 + 1e-12
    assert g.path(np.array([0.0]), np.array([0.5])) is not None
    assert g.path(np.array([0.0]), np.array([1.0])) is None
    assert g.components() == 2


def test_bridges_join_an_isolated_node_one_period_per_edge():
    """A node farther than one period from every other is linked by poses on the straight line to its nearest
    (travel time), every edge within one period; a wall on every line keeps it apart."""
    nodes = np.array([[0.0], [0.1], [0.2], [0.6]])
    free = lambda a, b: True  # noqa: E731
    assert TransitionGraph.build(nodes, np.array([0.15]), free, neighbours=4).component_sizes() == [3, 1]
    g = TransitionGraph.build(nodes, np.array([0.15]), free, neighbours=4, bridge_candidates=5)
    assert g.components() == 1 and g.sampled == 4
    assert np.allclose(np.sort(g.bridges[:, 0]), [0.2 + 0.4 / 3, 0.2 + 0.8 / 3])  # 0.4 in three pieces of < 0.15
    for i in range(len(g.nodes)):
        for j in g.indices[g.indptr[i]:g.indptr[i + 1]]:
            assert abs(g.nodes[i, 0] - g.nodes[j, 0]) <= 0.15
    assert [float(p[0]) for p in g.path(np.array([0.0]), np.array([0.6]))] == pytest.approx([0.0, 0.1, 0.2, 0.2 + 0.4 / 3, 0.2 + 0.8 / 3, 0.6])
    walled = lambda a, b: not (min(a[0], b[0]) < 0.4 < max(a[0], b[0]))  # noqa: E731
    g = TransitionGraph.build(nodes, np.array([0.15]), walled, neighbours=4, bridge_candidates=5)
    assert g.component_sizes() == [3, 1] and len(g.bridges) == 0


def test_the_path_enters_at_the_nearest_node_the_straight_move_reaches_and_that_reaches_the_goal():
    """A wall at 0.2: from 0.21 the nearest node (0.2) is behind it, so the path enters at 0.3 (the paper's nearest
    node would give a first step through the wall); from 0.19 the nearest reachable node (0.1, 0.0) is cut off from
    the goal 0.5 by the wall, so with ``reachable`` no path starts there, nor from the nodes beyond it."""
    nodes = np.array([[0.0], [0.1], [0.2], [0.3], [0.4], [0.5]])
    wall = lambda a, b: not (min(a[0], b[0]) < 0.205 < max(a[0], b[0]))  # noqa: E731 - a wall at 0.205
    g = TransitionGraph.build(nodes, np.array([0.15]), wall, neighbours=4)
    assert g.component_sizes() == [3, 3]
    assert g.entry(np.array([0.21]), wall) == 3 and g.nearest(np.array([0.21])) == 2
    assert [float(p[0]) for p in g.path(np.array([0.21]), np.array([0.5]), wall)] == pytest.approx([0.3, 0.4, 0.5])
    assert g.path(np.array([0.19]), np.array([0.5]), wall) is None  # only 0.2, 0.1, 0.0 are reachable from it
    # a farther reachable candidate in the goal's component is taken when the nearest reachable one is cut off
    cut = TransitionGraph.build(np.array([[0.0], [0.3], [0.32], [0.5]]), np.array([0.25]),
                                lambda a, b: not (min(a[0], b[0]) < 0.2 < max(a[0], b[0])) or b[0] == 0.3 or a[0] == 0.3,
                                neighbours=4)
    assert [float(p[0]) for p in cut.path(np.array([0.19]), np.array([0.5]), lambda a, b: b[0] in (0.0, 0.3))] \
        == pytest.approx([0.3, 0.5])  # 0.0, nearer and reachable, is alone (0.3 away: more than one period)


def test_a_graph_whose_arrays_disagree_is_refused_and_an_empty_one_finds_nothing():
    nodes = np.zeros((3, 2))
    with pytest.raises(ValueError, match="adjacency over 3 nodes"):
        TransitionGraph(nodes, np.array([0, 1, 2, 3, 4]), np.array([1, 0, 2, 1]))  # indptr of a 4-node graph
    with pytest.raises(ValueError, match="indices < 3"):
        TransitionGraph(nodes, np.array([0, 1, 2, 2]), np.array([3, 0]))
    empty = TransitionGraph(np.zeros((0, 2)), np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64))
    assert empty.nearest(np.zeros(2)) is None and empty.path(np.zeros(2), np.ones(2)) is None
    assert empty.entry(np.zeros(2), lambda a, b: True) is None


def test_bridges_join_every_component_into_one():
    """Clusters two to three periods apart on a line: each joins the rest (smallest first), no walls."""
    rng = np.random.default_rng(0)
    centres = [0.0, 1.0, 2.5, 3.2]
    nodes = np.concatenate([c + rng.uniform(-0.05, 0.05, (5 if c else 20, 2)) for c in centres])
    g0 = TransitionGraph.build(nodes, np.array([0.3, 0.3]), lambda a, b: True, neighbours=6)
    assert g0.component_sizes() == [20, 5, 5, 5]
    g = TransitionGraph.build(nodes, np.array([0.3, 0.3]), lambda a, b: True, neighbours=6, bridge_candidates=3)
    assert g.components() == 1 and len(g.bridges) > 0
    for i in range(len(g.nodes)):
        for j in g.indices[g.indptr[i]:g.indptr[i + 1]]:
            assert np.all(np.abs(g.nodes[i] - g.nodes[j]) <= 0.3)


def test_cancelled_training_resumes_to_the_same_weights(tmp_path):
    """A run cancelled mid-way and resumed from its checkpoint ends with exactly the weights of a run that
    was never interrupted (saved optimiser and random states); a checkpoint of another config is refused."""
    import pytest
    import torch

    rng = np.random.default_rng(0)
    data = {"a": DomainData(rng.uniform(0, 1, (300, 3))), "b": DomainData(rng.uniform(0, 1, (300, 2)))}
    glue = {"a": data["a"].data[:40], "b": data["b"].data[:40]}
    cfg = TrainConfig(iterations=30, batch_size=16, seed=3)

    def fresh():
        return SharedLatentWAE({"a": 3, "b": 2}, latent_dim=2, hidden=8, seed=3)

    straight = fresh()
    train_wae(straight, data, glue, cfg)
    ckpt = tmp_path / "wae.pt"
    calls = iter(range(1000))
    with pytest.raises(KeyboardInterrupt):
        train_wae(fresh(), data, glue, cfg, should_stop=lambda: next(calls) >= 17, checkpoint=ckpt, checkpoint_every=5)
    assert ckpt.is_file()
    resumed = fresh()
    train_wae(resumed, data, glue, cfg, checkpoint=ckpt, checkpoint_every=5)
    for k, v in straight.state_dict().items():
        assert torch.equal(v, resumed.state_dict()[k]), k
    with pytest.raises(ValueError, match="another training configuration"):
        train_wae(fresh(), data, glue, TrainConfig(iterations=30, batch_size=16, seed=4), checkpoint=ckpt)

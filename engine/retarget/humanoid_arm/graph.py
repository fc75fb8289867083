"""Transition graph (§IV-C, after E-Graphs): nodes are LA-DPP-sampled collision-free poses; an edge joins
two poses whose straight-line interpolation is collision-free and short enough to be covered within one
control period at the joints' velocity limits. When the direct interpolation from the current pose to a
new target collides, both are matched to their nearest nodes and breadth-first search gives the
shortest (fewest-edges) path, which is then followed one node per control period. The current pose is matched
to the nearest node the straight move from it reaches (:meth:`TransitionGraph.entry`): the paper's nearest node
can be behind a collision, and the arm then holds its pose until the target moves.

A sampled pose whose every neighbour is more than one period away (or behind a collision) would make its own
component, and BFS from it finds nothing. :meth:`TransitionGraph.build` therefore joins the components, smallest
first: of the few nearest pairs of poses (in travel time) between a component and the others, the first whose straight
interpolation is collision-free is linked through poses on that line, spaced at most one period apart (*bridge* nodes,
appended after the sampled ones) — so every edge still keeps the one-period, collision-free rule.
"""

from __future__ import annotations

from collections import deque
from typing import Callable

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

InterpolationFree = Callable[[np.ndarray, np.ndarray], bool]


def bfs_path(indptr: np.ndarray, indices: np.ndarray, start: int, goal: int) -> list[int] | None:
    """Shortest path (fewest edges) in a CSR adjacency; None when unreachable."""
    if start == goal:
        return [start]
    parent = np.full(len(indptr) - 1, -1, dtype=np.int64)
    parent[start] = start
    queue = deque([start])
    while queue:
        u = queue.popleft()
        for v in indices[indptr[u]:indptr[u + 1]]:
            if parent[v] < 0:
                parent[v] = u
                if v == goal:
                    path = [int(v)]
                    while path[-1] != start:
                        path.append(int(parent[path[-1]]))
                    return path[::-1]
                queue.append(v)
    return None


def _is_edge(a: np.ndarray, b: np.ndarray, max_step_rad: np.ndarray, interpolation_free: InterpolationFree) -> bool:
    """The graph's edge rule: within one control period on every joint, and a collision-free straight move."""
    return bool(np.all(np.abs(b - a) <= max_step_rad)) and interpolation_free(a, b)


def _csr(adj: list[set[int]]) -> tuple[np.ndarray, np.ndarray]:
    indptr = np.zeros(len(adj) + 1, dtype=np.int64)
    indptr[1:] = np.cumsum([len(a) for a in adj])
    indices = np.array([j for a in adj for j in sorted(a)], dtype=np.int64)
    return indptr, indices


def _labels(indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Connected-component label of every node (scipy's union of the CSR adjacency)."""
    n = len(indptr) - 1
    graph = csr_matrix((np.ones(len(indices), dtype=np.int8), indices, indptr), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def _join_components(nodes: np.ndarray, max_step_rad: np.ndarray, interpolation_free: InterpolationFree,
                     adj: list[set[int]], candidates: int) -> list[np.ndarray]:
    """Link every component but the largest to another one (smallest first) through bridge poses on the straight,
    collision-free line between their nearest pair; ``adj`` grows by the bridges' edges. Each component tries its
    ``candidates`` nearest outside pairs (travel time: max_j |Δq_j| / max_step_j); one that none of them reaches
    stays apart. Returns the bridge poses (node ids len(nodes), len(nodes) + 1, …)."""
    scaled = nodes / max_step_rad
    bridges: list[np.ndarray] = []
    labels = _labels(*_csr(adj))[: len(nodes)]
    tried: set[int] = set()  # labels of components none of whose candidates could be linked
    while True:
        sizes = np.bincount(labels)
        live = [int(c) for c in np.argsort(sizes, kind="stable") if sizes[c] > 0]  # the largest last
        pending = [c for c in live[:-1] if c not in tried]
        if not pending:
            break
        c = pending[0]
        members = np.nonzero(labels == c)[0]
        others = np.nonzero(labels != c)[0]
        dist, near = cKDTree(scaled[others]).query(scaled[members], k=min(candidates, len(others)), p=np.inf)
        dist, near = np.reshape(dist, (len(members), -1)), np.reshape(near, (len(members), -1))
        pairs = sorted((float(dist[a, b]), int(members[a]), int(others[near[a, b]]))
                       for a in range(len(members)) for b in range(dist.shape[1]))[:candidates]
        linked = False
        for d, i, j in pairs:
            segments = int(np.floor(d)) + 1  # each piece strictly shorter than one period
            line = [nodes[i] + (t / segments) * (nodes[j] - nodes[i]) for t in range(1, segments)]
            chain = [nodes[i], *line, nodes[j]]
            if not all(_is_edge(a, b, max_step_rad, interpolation_free) for a, b in zip(chain, chain[1:])):
                continue
            ids = [i, *range(len(nodes) + len(bridges), len(nodes) + len(bridges) + len(line)), j]
            bridges.extend(line)
            adj.extend(set() for _ in line)
            for a, b in zip(ids, ids[1:]):
                adj[a].add(b)
                adj[b].add(a)
            labels[labels == c] = labels[j]
            tried.discard(int(labels[j]))  # the merged component has new members: it may now reach further
            linked = True
            break
        if not linked:
            tried.add(c)
    return bridges


class TransitionGraph:
    def __init__(self, nodes: np.ndarray, indptr: np.ndarray, indices: np.ndarray, sampled: int | None = None):
        """``nodes``: the sampled poses, then the bridge poses (``sampled``: how many are sampled; default all); the
        edges as a CSR adjacency over them. ValueError when the adjacency does not fit the nodes (a weights file whose
        graph arrays disagree: one line at load, not an IndexError while puppeteering)."""
        n = len(nodes)
        if len(indptr) != n + 1 or (len(indices) and not 0 <= int(np.min(indices)) <= int(np.max(indices)) < n) \
                or (n and int(indptr[-1]) != len(indices)):
            raise ValueError(f"transition graph: expected an adjacency over {n} nodes (indptr of {n + 1}, indices < {n}), "
                             f"got indptr of {len(indptr)} and indices up to "
                             f"{int(np.max(indices)) if len(indices) else '-'}")
        self.nodes, self.indptr, self.indices = nodes, indptr, indices
        self.sampled = n if sampled is None else int(sampled)
        self.tree = cKDTree(nodes) if n else None

    @classmethod
    def build(cls, nodes: np.ndarray, max_step_rad: np.ndarray, interpolation_free: InterpolationFree,
              neighbours: int = 12, progress: Callable[[int, int], None] | None = None,
              bridge_candidates: int = 0) -> "TransitionGraph":
        """Each node tries the nodes within one period (|Δq_j| ≤ max_step_rad_j), nearest in travel time first,
        until it has ``neighbours`` collision-free edges (at most 3 × ``neighbours`` tried). ``bridge_candidates``
        > 0: the components are then joined (:func:`_join_components`)."""
        scaled = nodes / max_step_rad
        tree = cKDTree(scaled)
        adj: list[set[int]] = [set() for _ in range(len(nodes))]
        k = min(3 * neighbours + 1, len(nodes))
        for i in range(len(nodes)):
            if len(adj[i]) < neighbours:
                dist, idx = tree.query(scaled[i], k=k, p=np.inf, distance_upper_bound=1.0 + 1e-9)
                for d, j in zip(np.atleast_1d(dist), np.atleast_1d(idx)):
                    j = int(j)
                    if not np.isfinite(d) or len(adj[i]) >= neighbours:
                        break
                    if j == i or j in adj[i]:
                        continue
                    if _is_edge(nodes[i], nodes[j], max_step_rad, interpolation_free):
                        adj[i].add(j)
                        adj[j].add(i)
            if progress is not None and (i + 1) % 200 == 0:
                progress(i + 1, len(nodes))
        bridges = _join_components(nodes, max_step_rad, interpolation_free, adj, bridge_candidates) if bridge_candidates > 0 else []
        all_nodes = np.concatenate([nodes, np.array(bridges).reshape(-1, nodes.shape[1])]) if bridges else nodes
        return cls(all_nodes, *_csr(adj), sampled=len(nodes))

    @property
    def bridges(self) -> np.ndarray:
        """The bridge poses (appended after the sampled nodes)."""
        return self.nodes[self.sampled:]

    def nearest(self, x: np.ndarray) -> int | None:
        """The node nearest to ``x`` (None in a graph without nodes)."""
        return None if self.tree is None else int(self.tree.query(x)[1])

    def entries(self, x: np.ndarray, reachable: InterpolationFree, candidates: int = 8) -> list[int]:
        """Of the ``candidates`` nodes nearest to ``x``, nearest first, those the straight move from ``x`` reaches
        (``reachable(x, node)``; a node at ``x`` itself always)."""
        if self.tree is None or candidates < 1:
            return []
        _, near = self.tree.query(x, k=min(candidates, len(self.nodes)))
        return [int(j) for j in np.atleast_1d(near)
                if np.max(np.abs(self.nodes[j] - x)) < 1e-9 or reachable(x, self.nodes[j])]

    def entry(self, x: np.ndarray, reachable: InterpolationFree, candidates: int = 8) -> int | None:
        """The nearest of :meth:`entries` (None when the straight move reaches none of them)."""
        found = self.entries(x, reachable, candidates)
        return found[0] if found else None

    def path(self, x_from: np.ndarray, x_to: np.ndarray, reachable: InterpolationFree | None = None,
             candidates: int = 8) -> list[np.ndarray] | None:
        """Node poses from near ``x_from`` to near ``x_to`` (None when not connected). The path starts at the node
        nearest to ``x_from`` (the paper), or with ``reachable`` at the nearest of :meth:`entries` from which BFS
        reaches the goal (None when none of them does), so its first step is feasible."""
        goal = self.nearest(x_to)
        if goal is None:
            return None
        starts = [self.nearest(x_from)] if reachable is None else self.entries(x_from, reachable, candidates)
        for start in starts:
            ids = None if start is None else bfs_path(self.indptr, self.indices, start, goal)
            if ids is not None:
                return [self.nodes[i] for i in ids]
        return None

    def component_sizes(self) -> list[int]:
        """Node count of every connected component, largest first."""
        return sorted(np.bincount(_labels(self.indptr, self.indices)).tolist(), reverse=True)

    def components(self) -> int:
        return len(self.component_sizes())


__all__ = ["bfs_path", "TransitionGraph"]

"""Transition graph (§IV-C, after E-Graphs): nodes are LA-DPP-sampled collision-free poses; an edge joins
two poses whose straight-line interpolation is collision-free and short enough to be covered within one
control period at the joints' velocity limits. When the direct interpolation from the current pose to a
new target collides, both are matched to their nearest nodes and breadth-first search gives the
shortest (fewest-edges) path, which is then followed one node per control period.
"""

from __future__ import annotations

from collections import deque
from typing import Callable

import numpy as np
from scipy.spatial import cKDTree


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


class TransitionGraph:
    def __init__(self, nodes: np.ndarray, indptr: np.ndarray, indices: np.ndarray):
        self.nodes, self.indptr, self.indices = nodes, indptr, indices
        self.tree = cKDTree(nodes)

    @classmethod
    def build(cls, nodes: np.ndarray, max_step_rad: np.ndarray, interpolation_free: Callable[[np.ndarray, np.ndarray], bool],
              neighbours: int = 12, progress: Callable[[int, int], None] | None = None) -> "TransitionGraph":
        """Edges to up to ``neighbours`` nearest nodes reachable in one period (|Δq_j| ≤ max_step_rad_j)."""
        tree = cKDTree(nodes / max_step_rad)
        adj: list[set[int]] = [set() for _ in range(len(nodes))]
        for i in range(len(nodes)):
            _, idx = tree.query(nodes[i] / max_step_rad, k=min(neighbours + 1, len(nodes)))
            for j in np.atleast_1d(idx):
                j = int(j)
                if j == i or j in adj[i]:
                    continue
                if np.all(np.abs(nodes[j] - nodes[i]) <= max_step_rad) and interpolation_free(nodes[i], nodes[j]):
                    adj[i].add(j)
                    adj[j].add(i)
            if progress is not None and (i + 1) % 200 == 0:
                progress(i + 1, len(nodes))
        indptr = np.zeros(len(nodes) + 1, dtype=np.int64)
        indptr[1:] = np.cumsum([len(a) for a in adj])
        indices = np.array([j for a in adj for j in sorted(a)], dtype=np.int64)
        return cls(nodes, indptr, indices)

    def nearest(self, x: np.ndarray) -> int:
        return int(self.tree.query(x)[1])

    def path(self, x_from: np.ndarray, x_to: np.ndarray) -> list[np.ndarray] | None:
        """Node poses from near ``x_from`` to near ``x_to`` (None when not connected)."""
        ids = bfs_path(self.indptr, self.indices, self.nearest(x_from), self.nearest(x_to))
        return None if ids is None else [self.nodes[i] for i in ids]

    def components(self) -> int:
        seen = np.zeros(len(self.nodes), dtype=bool)
        count = 0
        for s in range(len(self.nodes)):
            if seen[s]:
                continue
            count += 1
            seen[s] = True
            queue = deque([s])
            while queue:
                u = queue.popleft()
                for v in self.indices[self.indptr[u]:self.indptr[u + 1]]:
                    if not seen[v]:
                        seen[v] = True
                        queue.append(v)
        return count


__all__ = ["bfs_path", "TransitionGraph"]

"""Douglas-Peucker by edge splits, the worst edge first (meier.md 1.3 step 4, A3-A7): a closed
contour is approximated by some of its corners, refined one split at a time so that a split
rate can ration them.

A ring starts from its mandatory corners (where the crack type changes: each polygon edge
has one type) or, with none, from the contour's lowest (y, x) corner and the corner farthest
from it (a digon). Each edge's error is the largest distance from a corner of its arc to the
edge's closed segment; a split inserts that corner (ties: the first along the contour). The
edge with the largest error is split first (ties: the lowest start index), and refinement
stops once no error exceeds eps. Corners a contour passes twice (pinches) are never vertices.
Run to the end, the vertices are those of a plain recursive Douglas-Peucker from the same
start, whatever the order the splits took.
"""
from __future__ import annotations

import heapq

import numpy as np


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from each point (rows of p) to the closed segment a-b."""
    p = np.asarray(p, np.float64)
    a = np.asarray(a, np.float64)
    ab = np.asarray(b, np.float64) - a
    denom = float(ab @ ab)
    t = np.zeros(len(p)) if denom == 0.0 else np.clip((p - a) @ ab / denom, 0.0, 1.0)
    closest = a + t[:, None] * ab
    return np.hypot(p[:, 0] - closest[:, 0], p[:, 1] - closest[:, 1])


class RingSimplifier:
    """The approximation of one closed contour: `vertices` (indices into its corners, in
    contour order) and the edges still worth a split."""

    def __init__(self, corners: np.ndarray, edge_types: np.ndarray, eps: float,
                 vertices: list[int] | None = None, usable: np.ndarray | None = None) -> None:
        """vertices: corner indices the ring has already (the mandatory ones are added);
        usable: which corners may be vertices (default: those the contour passes once)."""
        self.corners = np.asarray(corners, np.int64)
        self.eps = eps
        n = len(self.corners)
        if usable is None:
            keys = [tuple(c) for c in self.corners.tolist()]
            counts: dict[tuple[int, int], int] = {}
            for k in keys:
                counts[k] = counts.get(k, 0) + 1
            usable = np.array([counts[k] == 1 for k in keys], bool)      # not a pinch
        self._usable = np.asarray(usable, bool)
        types = self.edge_types = np.asarray(edge_types)
        mandatory = [k for k in range(n) if types[k] != types[k - 1] and self._usable[k]]
        if vertices:
            mandatory = sorted(set(mandatory) | set(vertices))
        elif not mandatory:
            mandatory = self._start_pair()
        self.vertices = sorted(mandatory)
        self._heap: list[tuple[float, int, int, int]] = []     # (-error, start, end, split corner)
        for i, s in enumerate(self.vertices):
            self._push(s, self.vertices[(i + 1) % len(self.vertices)])

    def _start_pair(self) -> list[int]:
        usable = np.nonzero(self._usable)[0]
        if len(usable) == 0:
            return [0]
        order = np.lexsort((self.corners[usable, 0], self.corners[usable, 1]))
        v0 = int(usable[order[0]])
        d = np.hypot(*(self.corners[usable] - self.corners[v0]).T)
        v1 = int(usable[int(np.argmax(d))])        # argmax: the first of equals along the contour
        return [v0] if v1 == v0 else [v0, v1]

    def _arc(self, s: int, e: int) -> np.ndarray:
        """Corner indices strictly between s and e along the contour."""
        n = len(self.corners)
        length = (e - s) % n or n
        return (s + np.arange(1, length)) % n

    def _push(self, s: int, e: int) -> None:
        arc = self._arc(s, e)
        arc = arc[self._usable[arc]]
        if not len(arc):
            return
        d = point_segment_distance(self.corners[arc], self.corners[s], self.corners[e])
        k = int(np.argmax(d))
        if d[k] > self.eps:
            heapq.heappush(self._heap, (-float(d[k]), s, e, int(arc[k])))

    @property
    def worst_error(self) -> float:
        """The largest error of any edge still above eps (0 when converged)."""
        return -self._heap[0][0] if self._heap else 0.0

    def split(self) -> int | None:
        """Split the worst edge; the corner inserted, or None if none is above eps."""
        if not self._heap:
            return None
        _, s, e, k = heapq.heappop(self._heap)
        self.vertices = sorted(self.vertices + [k])
        self._push(s, k)
        self._push(k, e)
        return k


def douglas_peucker(corners: np.ndarray, start: list[int], eps: float, usable: np.ndarray) -> list[int]:
    """Plain recursive Douglas-Peucker of the closed contour from the given start vertices
    (same distance and tie rules as RingSimplifier): the reference the tests compare with."""
    n = len(corners)
    out = set(start)

    def recurse(s: int, e: int) -> None:
        length = (e - s) % n or n
        arc = (s + np.arange(1, length)) % n
        arc = arc[usable[arc]]
        if not len(arc):
            return
        d = point_segment_distance(corners[arc], corners[s], corners[e])
        k = int(np.argmax(d))
        if d[k] > eps:
            out.add(int(arc[k]))
            recurse(s, int(arc[k]))
            recurse(int(arc[k]), e)

    start = sorted(start)
    for i, s in enumerate(start):
        recurse(s, start[(i + 1) % len(start)])
    return sorted(out)

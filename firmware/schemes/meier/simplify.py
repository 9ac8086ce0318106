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

from firmware.schemes.meier.contours import rotated


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from each point (rows of p) to the closed segment a-b: one segment for all
    points, or one per point (rows of a and b)."""
    p = np.asarray(p, np.float64)
    a = np.asarray(a, np.float64)
    ab = np.asarray(b, np.float64) - a
    ab_x, ab_y = ab[..., 0], ab[..., 1]
    denom = ab_x * ab_x + ab_y * ab_y
    dx, dy = p[:, 0] - a[..., 0], p[:, 1] - a[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(denom == 0.0, 0.0, np.clip((dx * ab_x + dy * ab_y) / denom, 0.0, 1.0))
    return np.hypot(dx - t * ab_x, dy - t * ab_y)


class RingSimplifier:
    """The approximation of one closed contour: `vertices` (indices into its corners, in
    contour order) and the edges still worth a split."""

    def __init__(self, corners: np.ndarray, edge_types: np.ndarray, eps: float,
                 vertices: list[int] | None = None, usable: np.ndarray | None = None) -> None:
        """vertices: corner indices the ring has already (the mandatory ones are added);
        usable: which corners may be vertices (default: those the contour passes once)."""
        self.corners = np.asarray(corners, np.int64)
        self.eps = eps
        if usable is None:
            keys = [tuple(c) for c in self.corners.tolist()]
            counts: dict[tuple[int, int], int] = {}
            for k in keys:
                counts[k] = counts.get(k, 0) + 1
            usable = np.array([counts[k] == 1 for k in keys], bool)      # not a pinch
        self._usable = np.asarray(usable, bool)
        types = self.edge_types = np.asarray(edge_types)
        mandatory = np.nonzero((types != rotated(types, -1)) & self._usable)[0].tolist()
        if vertices:
            mandatory = sorted(set(mandatory) | set(vertices))
        elif not mandatory:
            mandatory = self._start_pair()
        self.vertices = sorted(mandatory)
        self._heap: list[tuple[float, int, int, int]] = []     # (-error, start, end, split corner)
        self._push_all()

    def _push_all(self) -> None:
        """_push for every edge at once: the contour rotated to start at the first vertex,
        each edge's arc is a run of corners."""
        n, v0 = len(self.corners), self.vertices[0]
        ends = [v - v0 for v in self.vertices[1:]] + [n]
        order = (v0 + np.arange(n)) % n
        edge = np.repeat(np.arange(len(ends)), np.diff([0] + ends))       # rotated corner -> its edge
        starts = np.array(self.vertices)
        stops = np.array(self.vertices[1:] + self.vertices[:1])
        d = point_segment_distance(self.corners[order], self.corners[starts[edge]], self.corners[stops[edge]])
        inner = np.ones(n, bool)
        inner[np.array([0] + ends[:-1])] = False                            # the edges' own start corners
        d[~(inner & self._usable[order])] = -1.0
        heads = np.array([0] + ends[:-1])
        worst = np.maximum.reduceat(d, heads)
        idx = np.arange(n)
        first = np.minimum.reduceat(np.where(d == worst[edge], idx, n), heads)   # the first of equals
        for i in np.nonzero(worst > self.eps)[0].tolist():
            self._heap.append((-float(worst[i]), int(starts[i]), int(stops[i]), int(order[first[i]])))
        heapq.heapify(self._heap)

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

    def vertex_edge_types(self) -> list[int]:
        """The type of each polygon edge (from each vertex to the next, in `vertices` order):
        a wall only if every crack along it is one, so that no frontier is ever drawn as a
        wall (a type change at a pinch corner, which is never a vertex, mixes types)."""
        v0 = self.vertices[0]
        return np.minimum.reduceat(rotated(self.edge_types, v0), [v - v0 for v in self.vertices]).tolist()

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

"""From one map to the next (meier.md 1.3): the polygon map follows the boundary of the
observed area as it grows, changing only what the new boundary forces and refining with the
splits it is given.

Each update traces the new boundary (contours.trace_contours), then:
1. vanish: a vertex whose corner is no longer on the boundary, or is a pinch, goes;
2. rings: the vertices left on each contour, in the contour's order, are its ring (a
   boundary broken in two, or two joined, is the same relink); a contour left with one
   vertex gets the corner farthest from it, one with none starts from its lowest corner
   and the farthest from that (meier.md A7); a free region too small to hold the robot's
   body gets no ring (no robot can go there, so no teammate needs it), nor does a hole too
   small to send anyone to (a table, a pillar, a pocket not seen into: a receiver draws it
   free, and its own LiDAR finds the obstacle); in a cluttered office such specks and
   holes are most of the rings and of the churn; a corner where the crack type
   changes is a vertex, unless a vertex a few wall cracks back can hold that junction
   (contours.hold_junctions), and a vertex's edge is a wall only if every crack along it
   is one;
3. refine: up to max_splits edge splits, the worst edge of all rings first (simplify).
Vertices never move: a vertex stays where it was sent or goes (the paper's constraint).
"""
from __future__ import annotations

import numpy as np

from firmware.schemes.meier.contours import Contour, hold_junctions, signed_area, smooth_edge_types, trace_contours
from firmware.schemes.meier.polygons import PolygonMap
from firmware.schemes.meier.replica import PolyRecord
from firmware.schemes.meier.simplify import RingSimplifier


class PolygonTracker:
    def __init__(self, sender_id: int, eps_cells: float, type_min_run: int = 1, junction_hold: int = 0,
                 min_region_cells: float = 0.0, min_hole_cells: float = 0.0) -> None:
        self.map = PolygonMap(sender_id)
        self.eps = eps_cells
        self.min_region_cells = min_region_cells    # free regions of less area are not traced
        self.min_hole_cells = min_hole_cells        # nor are holes of less area
        self.type_min_run = type_min_run    # cracks: shorter runs of one type take the type around
        self.junction_hold = junction_hold  # cracks: a junction moves back onto a vertex this near
        # Per ring: its simplifier and the vertex id at each of its corners that is one.
        self._rings: list[tuple[RingSimplifier, dict[int, int]]] = []
        # The rings as the last update left them, by their contour (corners, crack types,
        # usable corners) and vertices: a contour that comes back with the same vertices and
        # held crack types has the same ring (most of them, once a room is seen), and is not
        # simplified again.
        self._unchanged: dict[tuple, tuple[RingSimplifier, dict[int, int]]] = {}
        self.splits = 0          # edge splits the last update made

    def update(self, state: np.ndarray, max_splits: int, row0: int = 0, col0: int = 0) -> list[PolyRecord]:
        """Follow the boundary of `state` (a classified grid whose cell (0, 0) is cell
        (row0, col0) of the lattice; vertices sit on the lattice's corners); the records of
        what changed."""
        traced = [Contour(c.corners + (col0, row0), c.edge_types) for c in trace_contours(state)]
        usable, on = self._vertices_on(traced)
        self._rings, sources = [], []
        for label, c in enumerate(traced):
            if self._too_small(c.corners):
                continue
            ids = on.get(label, {})
            types = hold_junctions(smooth_edge_types(c.edge_types, self.type_min_run), sorted(ids),
                                   self.junction_hold)
            source = (c.corners.tobytes(), c.edge_types.tobytes(), usable[label].tobytes())
            ring = self._unchanged.get((*source, tuple(sorted(ids.items()))))
            if ring is None or not np.array_equal(ring[0].edge_types, types):
                ring = self._ring_on(Contour(c.corners, types), usable[label], ids)
            if ring is not None:
                self._rings.append(ring)
                sources.append(source)
        in_rings = {v for _, ids in self._rings for v in ids.values()}
        for v in self.map.live_vertices():
            if v not in in_rings:              # off the boundary, on a pinch, or on a contour too small
                self.map.vanish(v)
        self.map.relink([[ids[k] for k in rs.vertices] for rs, ids in self._rings])
        self.splits = self._refine(max_splits)
        for rs, ids in self._rings:
            for k, t in zip(rs.vertices, rs.vertex_edge_types()):
                self.map.set_edge_type(ids[k], t)
        self._unchanged = {(*source, tuple(sorted(ids.items()))): (rs, ids)
                           for source, (rs, ids) in zip(sources, self._rings)}
        return self.map.flush()

    @property
    def worst_error(self) -> float:
        """The largest distance (lattice units) from a boundary corner to its polygon edge,
        beyond eps (0 when every edge is within eps)."""
        return max((rs.worst_error for rs, _ in self._rings), default=0.0)

    def _too_small(self, corners: np.ndarray) -> bool:
        """Is this the outer boundary of a free region of less than min_region_cells, or a
        hole (clockwise) of less than min_hole_cells?"""
        area = signed_area(corners)
        return 0.0 < area < self.min_region_cells or 0.0 < -area < self.min_hole_cells

    def _vertices_on(self, contours: list[Contour]) -> tuple[list[np.ndarray], dict[int, dict[int, int]]]:
        """Per contour, which of its corners are usable (the boundary passes them once: not a
        pinch, even with a region too small to trace), and the live vertices on usable
        corners as {contour: {position: vertex}}."""
        if not contours:
            return [], {}
        lengths = np.array([len(c.corners) for c in contours])
        starts = np.cumsum(lengths) - lengths
        keys = _corner_keys(np.concatenate([c.corners for c in contours]))
        unique, first, inverse, passes = np.unique(keys, return_index=True, return_inverse=True, return_counts=True)
        usable = np.split(passes[inverse] == 1, starts[1:])
        on: dict[int, dict[int, int]] = {}
        live = self.map.live_vertices()
        if live:
            wanted = _corner_keys(np.array([self.map.vertex(v)[:2] for v in live], np.int64))
            at = np.minimum(np.searchsorted(unique, wanted), len(unique) - 1)
            hit = (unique[at] == wanted) & (passes[at] == 1)
            label_of = np.repeat(np.arange(len(contours)), lengths)
            position_of = np.arange(len(keys)) - starts[label_of]
            corner = first[at[hit]]
            for v, label, k in zip(np.asarray(live)[hit].tolist(), label_of[corner].tolist(),
                                   position_of[corner].tolist()):
                on.setdefault(label, {})[k] = v
        return usable, on

    def _ring_on(self, c: Contour, usable: np.ndarray, ids: dict[int, int]):
        """The ring of one contour: its simplifier, and the vertex id at each of its vertex
        corners (new vertices made for the corners it lacked); None if it has fewer than
        two usable corners."""
        if usable.sum() < 2:
            return None
        rs = RingSimplifier(c.corners, c.edge_types, self.eps, sorted(ids) or None, usable)
        if len(rs.vertices) < 2:
            d = np.hypot(*(c.corners - c.corners[rs.vertices[0]]).T)
            d[~usable] = -1.0
            rs = RingSimplifier(c.corners, c.edge_types, self.eps, rs.vertices + [int(np.argmax(d))], usable)
        ids = dict(ids)
        for k in rs.vertices:
            if k not in ids:
                x, y = (int(v) for v in c.corners[k])
                ids[k] = self.map.add_vertex(x, y, int(c.edge_types[k]))
        return rs, ids

    def _refine(self, max_splits: int) -> int:
        """Split the worst edge of all rings, up to max_splits times; how many it split."""
        for done in range(max_splits):
            if not self._rings:
                return done
            rs, ids = max(self._rings, key=lambda r: r[0].worst_error)
            k = rs.split()
            if k is None:
                return done
            before = ids[rs.vertices[rs.vertices.index(k) - 1]]
            x, y = (int(v) for v in rs.corners[k])
            ids[k] = self.map.split_edge(before, x, y)
        return max_splits


def _corner_keys(corners: np.ndarray) -> np.ndarray:
    """One int64 per lattice corner (x, y), |x|, |y| < 2**31."""
    xy = np.asarray(corners, np.int64)
    return (xy[:, 0] << 32) | (xy[:, 1] + (1 << 31))

"""Algorithm 1 (the paper's topological map building, III-A) fed with poses and scans.

The paper's rule: compute the descriptor of the current view; if no vertex of the map
scores `th` or more, build a new vertex (descriptor, position, unexplored directions) with
an edge from the last vertex and send both; else, if the best-scoring vertex is not the last
one, add and send an edge to it and make it the last vertex.

Two readings (mrtopomap.md A4, A5, A18), `novelty=`:
  "distance" (default, the spec's): novelty is decided by distance in the own frame: a new
      vertex is built only farther than d_vertex (2.5 m) from every vertex held (own, and
      merged teammates' in the own frame); a LiDAR descriptor aliases across corridors, so
      a global "score >= th means known" test would stop building in every corridor (the
      paper's Fig. 10 failure). The descriptor decides re-entry (line 22): the best-scoring
      vertex within r_reentry (4 m) scoring th_build (0.97, the released code's threshold)
      or more, if it is not the last vertex and lies nearer than the last vertex does, gets
      the edge and becomes the last vertex (without that nearness rule, edges flap between
      the vertex just built and the one behind it wherever a corridor repeats itself).
  "descriptor" (the paper's literal rule, for ablations): new iff the best score over every
      vertex held is below th_build; else re-entry to the best-scoring vertex.
Either way Algorithm 1 runs at most every eval_every_m of travel or eval_every_us of scan
time (A18); the first observation builds vertex 0 unless a merged teammate's vertex is near
(then that one becomes the last vertex, so the first own vertex's line-17 edge goes to it). Vertex ids rise by one from
first_id; positions are the record's (0.1 m), so what a teammate holds is what the builder
compared against.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np

from firmware.schemes.mr_topomap import descriptor as desc
from firmware.schemes.mr_topomap.directions import Cluster, Directions
from firmware.schemes.mr_topomap.params import DEFAULT, MrTopoParams
from firmware.schemes.mr_topomap.records import MAX_VERTEX_ID, NO_VERTEX, Edge, Vertex

_DM_MAX = (1 << 15) - 1


class Place(NamedTuple):
    """A vertex as the builder compares against it: key, position in the OWN frame (m),
    descriptor (a teammate's still in its owner's frame: Score does not care)."""

    owner: int
    vid: int
    x_m: float
    y_m: float
    desc: desc.Descriptor


class NewVertex(NamedTuple):
    vertex: Vertex                       # the mrvtx to send (its line-17 edge in prev_owner/prev_id)
    clusters: tuple[Cluster, ...]        # the frontier clusters behind its sectors (kept locally)


class ReEntry(NamedTuple):
    edge: Edge                           # the mredge to send (line 22)


class VertexBuilder:
    def __init__(self, robot_id: int, params: MrTopoParams = DEFAULT, first_id: int = 0,
                 novelty: str = "distance") -> None:
        assert novelty in ("distance", "descriptor"), f"novelty {novelty!r}: 'distance' or 'descriptor'"
        self.robot_id = robot_id
        self.p = params
        self.novelty = novelty
        self.next_id = first_id
        self.vertices: list[Vertex] = []
        self.clusters: dict[int, tuple[Cluster, ...]] = {}
        self.last: tuple[int, int] | None = None
        self.exhausted = 0               # observations that wanted a vertex after id 4094
        self._eval_xy: tuple[float, float] | None = None
        self._eval_us = 0
        self._xy = np.zeros((0, 2))
        self._codes = np.zeros((0, desc.BINS))

    def own_places(self) -> list[Place]:
        return [Place(v.owner, v.vid, v.x_m, v.y_m, v.desc) for v in self.vertices]

    def due(self, x_m: float, y_m: float, stamp_us: int) -> bool:
        """Algorithm 1 runs now (A18)."""
        if self._eval_xy is None:
            return True
        return (math.hypot(x_m - self._eval_xy[0], y_m - self._eval_xy[1]) >= self.p.eval_every_m
                or stamp_us - self._eval_us >= self.p.eval_every_us)

    def observe(self, x_m: float, y_m: float, yaw_rad: float, stamp_us: int, ranges_m: np.ndarray,
                angle_min_rad: float, angle_increment_rad: float, range_max_m: float,
                directions: Callable[[float, float], Directions] | None = None,
                others: Sequence[Place] = ()) -> list[NewVertex | ReEntry]:
        """One pose (odometry, at the scan's stamp) and its scan. `directions(x, y)` detects
        the unexplored directions where a vertex is built (called only then); `others` are
        merged teammates' vertices in the own frame (A5). Returns what to send."""
        if not self.due(x_m, y_m, stamp_us):
            return []
        self._eval_xy, self._eval_us = (x_m, y_m), stamp_us
        d_now = desc.describe(ranges_m, angle_min_rad, angle_increment_rad, yaw_rad, range_max_m, self.p)
        keys = [(v.owner, v.vid) for v in self.vertices] + [(o.owner, o.vid) for o in others]
        xy = self._xy if not others else np.concatenate([self._xy, [[o.x_m, o.y_m] for o in others]])
        codes = self._codes if not others else np.concatenate([self._codes, [o.desc.codes for o in others]])
        x_dm = int(np.clip(round(x_m * 10.0), -_DM_MAX - 1, _DM_MAX))
        y_dm = int(np.clip(round(y_m * 10.0), -_DM_MAX - 1, _DM_MAX))
        dist = np.hypot(xy[:, 0] - x_dm / 10.0, xy[:, 1] - y_dm / 10.0)
        scores = (desc.peaks(desc.shift_scores(desc.centred(codes), desc.centred(d_now.codes))[:, 0])[0]
                  if len(keys) else np.zeros(0))
        if self.novelty == "distance":
            new = not len(keys) or dist.min() > self.p.d_vertex_m
            pool = dist <= self.p.r_reentry_m
        else:
            new = not len(keys) or scores.max() < self.p.th_build
            pool = np.ones(len(keys), dtype=bool)
        if new:
            return self._build(x_dm, y_dm, d_now, directions)
        if self.last is not None and self.last in keys:
            # Re-entered a known place only when nearer to it than to the last vertex: in
            # corridors that look alike, the vertex behind scores as well as the one just built
            # and edges would flap between them.
            pool &= dist < dist[keys.index(self.last)]
        cand = np.flatnonzero(pool & (scores >= self.p.th_build))
        if cand.size == 0:
            return []
        best = int(cand[np.argmax(scores[cand])])      # first of the best: the lowest key
        matched = keys[best]
        if matched == self.last:
            return []
        if self.last is None:                 # no own vertex yet, at a merged teammate's: no edge to make
            self.last = matched
            return []
        edge = Edge(self.robot_id, self.last[0], self.last[1], matched[0], matched[1])
        self.last = matched
        return [ReEntry(edge)]

    def _build(self, x_dm: int, y_dm: int, d_now: desc.Descriptor,
               directions: Callable[[float, float], Directions] | None) -> list[NewVertex]:
        if self.next_id > MAX_VERTEX_ID:
            self.exhausted += 1
            return []
        found = directions(x_dm / 10.0, y_dm / 10.0) if directions is not None else Directions(0, ())
        prev_owner, prev_id = self.last if self.last is not None else (self.robot_id, NO_VERTEX)
        v = Vertex(self.robot_id, self.next_id, x_dm, y_dm, prev_owner, prev_id, found.ud_sectors, d_now)
        self.vertices.append(v)
        self.clusters[v.vid] = found.clusters
        self._xy = np.concatenate([self._xy, [[v.x_m, v.y_m]]])
        self._codes = np.concatenate([self._codes, [d_now.codes]])
        self.last = v.key
        self.next_id += 1
        return [NewVertex(v, found.clusters)]

"""Goal choice as Pereira et al. make it (pereira.md 1.5, 1.6, A7, A8, A10, A12): where the
robot is in the region graph, the four frontier categories, and Algorithm 1 with eq. (3).

These are private decisions: each robot places itself and its waypoints in its own region
graph (RegionGraph.label), as the paper's robots localise themselves in theirs.

- The current region C changes to a region L only after the robot has travelled margin_m
  with its position labelled L (the paper's margin, A8); P is the region held just before
  the last change (A7: none at the start, so every neighbour of C is "following").
- Categories, best first: f^fu (a following region nobody has entered: virtual, v = 0),
  f^c (C itself, or a neighbour of C within margin_m of a gate between them), f^fs (a
  following region entered but not explored), f^o (everything else, unlabelled included).
- Algorithm 1 walks the categories in order and takes the first frontier that is not in a
  region another robot is headed to, unless eq. (3) lets it have it anyway: its distance to
  the frontier is below that robot's distance to its own goal (every such robot's, A10;
  ties to the lower id). If every frontier conflicts, the first of the first category. As
  ranks for the shared choice: rank = category, plus 4 if it conflicts.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from firmware.schemes.pereira.regions import RegionGraph, near_segment

FU, CURRENT, FS, OTHER = 0, 1, 2, 3      # records.CATEGORIES order: fu, c, fs, o
CONFLICT_RANK = 4


class Whereabouts:
    """The current and previous region (by region id, which is stable while the region's
    smallest place stays its anchor), with the margin's hysteresis."""

    def __init__(self, margin_m: float) -> None:
        self.margin_m = margin_m
        self.current: tuple[int, ...] | None = None
        self.previous: tuple[int, ...] | None = None
        self._pending: tuple[tuple[int, ...], float, float] | None = None   # label, where first seen

    def update(self, graph: RegionGraph, here: int | None, x_m: float, y_m: float) -> None:
        """One look at the robot's label `here` (a region index of graph, or None)."""
        if self.current is not None and graph.region_index(self.current) is None:
            # C merged into another region or was renamed: the robot is where it stands.
            self.current, self._pending = (graph.regions[here].id if here is not None else None), None
            return
        if here is None:
            return
        label = graph.regions[here].id
        if self.current is None:
            self.current = label
            return
        if label == self.current:
            self._pending = None
            return
        if self._pending is None or self._pending[0] != label:
            self._pending = (label, x_m, y_m)
        if math.hypot(x_m - self._pending[1], y_m - self._pending[2]) >= self.margin_m:
            self.previous, self.current, self._pending = self.current, label, None

    def indices(self, graph: RegionGraph) -> tuple[int | None, int | None]:
        """(C, P) as region indices of graph (None where unknown)."""
        c = graph.region_index(self.current) if self.current is not None else None
        p = graph.region_index(self.previous) if self.previous is not None else None
        return c, p


def categorise(graph: RegionGraph, labels: Sequence[int | None], xy_m: Sequence[tuple[float, float]],
               current: int | None, previous: int | None, explored: set[int], margin_m: float) -> list[int]:
    """Each frontier's category from its region label. `explored`: regions this robot
    judges explored or hears are (their frontiers are excluded before, so a following
    region here is semi-explored unless nobody entered it)."""
    if current is None:
        return [OTHER] * len(labels)
    neighbours = set(graph.neighbours(current))
    following = neighbours - {previous}
    margin_cm = int(round(margin_m * 100))
    out = []
    for r, (x, y) in zip(labels, xy_m):
        if r is None:
            out.append(OTHER)
            continue
        if r == current:
            out.append(CURRENT)
            continue
        if r in neighbours and margin_cm > 0:
            segs = graph.segments_cm[list(graph.gates_between(current, r))]
            px, py = int(round(x * 100)), int(round(y * 100))
            if len(segs) and bool(np.any(near_segment(px, py, segs[:, 0], segs[:, 1], segs[:, 2], segs[:, 3],
                                                      margin_cm))):
                out.append(CURRENT)
                continue
        if r in following:
            out.append(FU if graph.regions[r].virtual else (OTHER if r in explored else FS))
            continue
        out.append(OTHER)
    return out


def conflicts(distance_m: float, own_id: int, heading: Sequence[tuple[float, int]]) -> bool:
    """Eq. (3): does a frontier at distance_m from this robot, in a region that the robots in
    `heading` ((distance to its goal in m, id), each) are headed to, belong to one of them?
    This robot takes it only if it is closer than every one of them is to its own goal."""
    return any(not (distance_m < d or (distance_m == d and own_id < rid)) for d, rid in heading)

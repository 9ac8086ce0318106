"""MR-TopoMap (Zhang et al., RA-L 2022) as a scheme: a topological map whose vertices carry a
LiDAR place descriptor and unexplored directions, shared over LoRa in 30-byte records, and
merged between robots WITHOUT a common frame (mrtopomap.md; issue 25).

Each robot runs Algorithm 1 on its own odometry and scans (vertices.py): a vertex farther
than d_vertex from every vertex it holds (own, and merged teammates' in its frame), with
the descriptor of the scan there and the unexplored directions its map shows around it
(directions.py), goes on the air as an `mrvtx` with its line-17 edge; a re-entry edge as an
`mredge`. Directions it finds explored, or takes as its goal, go as `mrud` clear masks.
Positions on the air are in the SENDER'S OWN odometry frame: the scheme never needs a
shared frame, and runs with `--frames own`.

Per teammate it estimates T_own<-teammate from the records held (merge.py: descriptor
hypotheses against its own vertices and a profile grid of its own map, consensus, ratio
test, occupancy and view checks; a pure function of the records, so merges revise
themselves), every merge_period_s when something changed, sends its direct merges as
`mrlink` records and weighs them against its teammates' (links.py: outvoted merges,
merges by composition). Variant `literal`: the
paper's own translation-only merge on the first match, with SMMR's outlier rule
(literal.py), as an ablation.

Once a teammate's frame is merged, its vertices (moved into the own frame) count in
Algorithm 1 (no own vertex is built next to one, A5), its open directions are goals like
the own ones, its vertices' centre enters eq. (1), and own waypoints it evidently saw
(a vertex of its within team_near_m in line of sight, no open direction of it
near) are left to it.

Its planning stage (the shared planner chooses, routes and keeps strikes):
  - directions explored are cleared (III-E, A12): the robot came within explored_radius of
    the direction's point, or no frontier cell of its own map connected to it is left that
    close to it (own vertices: the frontier cluster's centroid they were built from;
    teammates': vertex + distance-class midpoint along the sector, known in the own map);
  - the goal (III-D): after a new own vertex with open directions, a goal reached or lost,
    or a change of merge, the open direction of the current vertex (Algorithm 1's
    last_vertex) with the highest eq. (1) score, w * d(c_own, f) + (1 - w) / m * sum over
    the m merged teammates of d(c_j, f), ranks first; once the robot heads there it is
    cleared and announced (the paper deletes a chosen direction) and stays the goal until
    it ends. Without a direction at the current vertex, the best direction of every vertex
    that has one ranks with the own waypoints, and the nearest is taken (the paper's
    fallback: the nearest vertex with a direction);
  - own waypoints (the shared frontier waypoints) rank after the goal: the frontier-based
    completion the spec's termination (A17) asks for. The robot stops when no direction it
    can reach is open anywhere in its merged map and no frontier is left (the shared rule).
Beyond the local window it routes along its own places (a vertex every d_build_m, never
sent), as `independent` does.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
import scipy.ndimage as ndimage
from scipy.spatial import cKDTree

from firmware import kernels
from firmware.scheduler import Task
from firmware.schemes.base import (PRIORITY_INFO, PRIORITY_MOTION, Candidate, OwnPlaces, PlanningView, Scheme,
                                   Services, cost_along_graph)
from firmware.schemes.mr_topomap import directions as dirs
from firmware.schemes.mr_topomap import links
from firmware.schemes.mr_topomap.literal import LiteralMerge
from firmware.schemes.mr_topomap.merge import SE2, MergeResult, OwnMap, ProfileGrid, TeammateMerge, VertexSet, within
from firmware.schemes.mr_topomap.params import DEFAULT, MrTopoParams
from firmware.schemes.mr_topomap.records import (DIALECT, NO_VERTEX, Link, link_values, sector_class,
                                                 vertex_from_values, vertex_values)
from firmware.schemes.mr_topomap.vertices import NewVertex, Place, ReEntry, VertexBuilder
from firmware.services.grid_paths import lines_of_sight, nearest_traversable
from firmware.services.targets import Target
from hal.samples import OdometrySample

_FOUR = ndimage.generate_binary_structure(2, 1)
SNAP_M = 2.0              # a direction's goal: the reachable cell nearest its point, this close at most
UNREACHABLE_CYCLES = 3    # a direction in the window with no reachable cell near it this many plans is given up here
_OWN_TYPES = ("mrvtx", "mredge", "mrud", "mrlink")


class Direction(NamedTuple):
    key: tuple[int, int]          # its vertex (owner, id)
    sector: int
    x_m: float                    # its point in the own frame: cluster centroid (own) or vertex + class midpoint
    y_m: float
    vx_m: float                   # its vertex in the own frame
    vy_m: float
    own: bool                     # an own vertex's (its point is the cluster's centroid)


class Goal(NamedTuple):
    key: tuple[int, int]
    sector: int
    x_m: float                    # where the robot heads (a reachable cell near the direction's point)
    y_m: float


class MrTopoMap(Scheme):
    name = "mrtopomap"
    doc = "MR-TopoMap: topological map with LiDAR place descriptors over LoRa, merged without a common frame"
    variants = {"": "frame-free SE(2) merge (consensus, ratio test, own-map checks), eq. (1) over the merged map",
                "literal": "the paper's own merge as an ablation: translation only, first match, SMMR's rule"}
    dialect = DIALECT
    needs = frozenset({"radio"})
    params_type = MrTopoParams

    def __init__(self, variant: str = "", params: MrTopoParams | None = None) -> None:
        super().__init__(variant)
        self.pp = params if params is not None else DEFAULT

    def attach(self, services: Services) -> None:
        super().attach(services)
        self.me = services.robot_id
        self.builder = VertexBuilder(self.me, self.pp)
        self.book = dirs.DirectionBook()
        self.mergers: dict[int, TeammateMerge | LiteralMerge] = {}
        self.results: dict[int, MergeResult] = {}
        self.edges: set[tuple[tuple[int, int], tuple[int, int]]] = set()
        self._own_places = OwnPlaces(services)
        self._own_set: VertexSet | None = None
        self._grid: ProfileGrid | None = None
        self._own_map: OwnMap | None = None
        self._grid_token = 0
        self._grid_us: int | None = None
        self._grid_vertices = -1
        self._dirty: set[int] = set()
        self._direct: dict[int, SE2] = {}                  # teammate -> T_own<-teammate, the own merge
        self._merged: dict[int, SE2] = {}                  # ... weighed against teammates' links (links.py)
        self.resolved: dict[int, links.Resolved] = {}
        self._links: dict[tuple[int, int], SE2] = {}       # (sender, peer) -> T_sender<-peer heard
        self._links_sent: dict[int, tuple[SE2 | None, int]] = {}   # peer -> what was sent last, when
        self._team_xy: dict[int, np.ndarray] = {}          # teammate -> its vertices in the own frame
        self._team_keys: dict[int, list[tuple[int, int]]] = {}
        self._merged_places: list[Place] = []
        self._said_clear: dict[tuple[int, int], int] = {}  # vertex -> sectors this robot announced cleared
        self._goal: Goal | None = None
        self._regoal = True
        self._offered: dict[tuple[float, float], Direction] = {}   # this cycle's direction candidates
        self._unreachable: dict[tuple[tuple[int, int], int], int] = {}
        self._given_up: set[tuple[tuple[int, int], int]] = set()
        self._woken_us = -(1 << 62)
        self.counts = dict.fromkeys((
            "vertices_sent", "reentry_edges_sent", "ud_records_sent", "vertices_heard", "edges_heard", "ud_heard",
            "goals_taken", "directions_explored", "directions_given_up", "waypoints_left_to_team", "merge_runs",
            "grid_renders", "records_dropped_by_link", "vertex_ids_exhausted", "wake_ups", "links_sent",
            "links_heard", "merges_outvoted", "merges_transitive"), 0)

    def tasks(self) -> list[Task]:
        return [Task("mrtopo_merge", 1.0 / self.pp.merge_period_s, self._task_merge)]

    # --- own vertices (Algorithm 1) --------------------------------------------------
    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        self._own_places.on_travel(pose)
        if not self.s.has_planned():
            return
        last = self.s.last_scan()
        if last is None:
            return
        x_m, y_m, yaw_rad, scan = last
        if not self.builder.due(x_m, y_m, scan.stamp_us):
            return
        for ev in self.builder.observe(x_m, y_m, yaw_rad, scan.stamp_us, scan.ranges_m, scan.angle_min_rad,
                                       scan.angle_increment_rad, scan.range_max_m, self._detect,
                                       self._merged_places):
            if isinstance(ev, NewVertex):
                v = ev.vertex
                self.book.add_vertex(v.key, v.ud_sectors)
                self._own_set = None
                if v.prev_id != NO_VERTEX:
                    self.edges.add(((v.prev_owner, v.prev_id), v.key))
                self._send("mrvtx", vertex_values(v), PRIORITY_MOTION)
                self.counts["vertices_sent"] += 1
                if v.ud_sectors:
                    self._regoal = True      # III-D3 (a): a new vertex with directions
            elif isinstance(ev, ReEntry):
                e = ev.edge
                self.edges.add(((e.n1, e.id1), (e.n2, e.id2)))
                self._send("mredge", {"sender_id": e.sender, "n1": e.n1, "id1": e.id1, "n2": e.n2, "id2": e.id2},
                           PRIORITY_INFO)
                self.counts["reentry_edges_sent"] += 1
        self.counts["vertex_ids_exhausted"] = self.builder.exhausted

    def _detect(self, x_m: float, y_m: float) -> dirs.Directions:
        """Algorithm 1 lines 15-16: the unexplored directions around a new vertex."""
        lm, res = self.s.local_map, self.s.params.resolution_m
        half = int(math.ceil(self.pp.ud_crop_m / 2.0 / res)) + 2
        i, j = lm.cell_of(x_m, y_m)
        i0, i1, j0, j1 = max(0, i - half), min(lm.n, i + half + 1), max(0, j - half), min(lm.n, j + half + 1)
        if i0 >= i1 or j0 >= j1:
            return dirs.Directions(0, ())
        return dirs.detect(lm.state_of(i0, i1, j0, j1), lm.row0 + i0, lm.col0 + j0, res, x_m, y_m, self.pp)

    def _own_vertices(self) -> VertexSet:
        if self._own_set is None:
            self._own_set = VertexSet(self.builder.vertices)
        return self._own_set

    def _send(self, rtype: str, values: Mapping[str, int], priority: int, key=None) -> None:
        if self.s.send is not None and not self.s.send(rtype, values, priority, key=key):
            self.counts["records_dropped_by_link"] += 1

    # --- what the robot hears --------------------------------------------------------
    def on_record(self, rtype: str, values: Mapping[str, int], now_us: int) -> None:
        if values["sender_id"] == self.me:
            return
        if rtype == "mrvtx":
            v = vertex_from_values(values)
            merger = self.mergers.get(v.owner)
            if merger is None:
                merger = self.mergers[v.owner] = (LiteralMerge(v.owner, self.pp) if self.variant == "literal"
                                                  else TeammateMerge(v.owner, self.pp))
            if merger.add(v):
                self.counts["vertices_heard"] += 1
                self.book.add_vertex(v.key, v.ud_sectors)
                if v.prev_id != NO_VERTEX:
                    self.edges.add(((v.prev_owner, v.prev_id), v.key))
                self._dirty.add(v.owner)
        elif rtype == "mredge":
            self.edges.add(((values["n1"], values["id1"]), (values["n2"], values["id2"])))
            self.counts["edges_heard"] += 1
        elif rtype == "mrud":
            self.book.clear((values["owner_id"], values["vertex_id"]), values["clear_mask"])
            self.counts["ud_heard"] += 1
        elif rtype == "mrlink":
            lk = Link(values["sender_id"], values["peer_id"], values["dx_dm"], values["dy_dm"], values["dyaw"],
                      values["support"])
            if lk.support:
                self._links[(lk.sender, lk.peer)] = links.transform_of(lk)
            else:
                self._links.pop((lk.sender, lk.peer), None)
            self.counts["links_heard"] += 1

    # --- merging (Algorithm 2, frame-free) ------------------------------------------
    def _task_merge(self, now_us: int) -> None:
        if not self.mergers or not self.s.has_planned() or self.s.last_scan() is None:
            return
        fresh_map = False
        if self.variant != "literal":
            fresh_map = self._refresh_grid(now_us)
        own = self._own_vertices()
        for j in sorted(self.mergers):
            # The literal merge also matches own vertices built since against what it holds.
            if j not in self._dirty and not fresh_map and self.variant != "literal":
                continue
            r = self.mergers[j].update(own, self._grid, self._own_map, own_map_token=self._grid_token)
            self.counts["merge_runs"] += 1
            self.results[j] = r
            self._direct.pop(j, None)
            if r.merged:
                self._direct[j] = r.T
        self._dirty = set()
        if self._with_links:
            self._send_links(now_us)
            centres = {j: m.vertices.xy.mean(axis=0) for j, m in self.mergers.items() if len(m.vertices)}
            was = {j: r.source for j, r in self.resolved.items()}
            self.resolved = links.resolve(self.me, self._direct, self._links, centres, self.pp)
            for j, r in self.resolved.items():
                if r.source != "direct" and was.get(j) != r.source:
                    self.counts[f"merges_{r.source}"] += 1
            merged = {j: r.T for j, r in self.resolved.items()}
        else:
            merged = dict(self._direct)
        changed = merged != self._merged
        self._merged = merged
        self._refresh_team()
        if changed:
            self._regoal = True          # III-D3 (c): right after a merge

    @property
    def _with_links(self) -> bool:
        return self.variant != "literal" and self.pp.link_period_s > 0

    def _send_links(self, now_us: int) -> None:
        """The own direct merges on the air (links.py): when made, moved or withdrawn, and
        again every link_period_s (a lost record is made good; a withdrawal, support 0, too)."""
        period_us = int(self.pp.link_period_s * 1e6)
        for j in sorted(set(self._direct) | set(self._links_sent)):
            T = self._direct.get(j)
            last = self._links_sent.get(j)
            if last is not None and now_us - last[1] < period_us and not self._link_moved(j, last[0], T):
                continue
            lk = links.link_of(self.me, j, T if T is not None else SE2(0.0, 0.0, 0.0),
                               self.results[j].support if T is not None else 0)
            self._send("mrlink", link_values(lk), PRIORITY_INFO, key=("mrlink", j))
            self._links_sent[j] = (T, now_us)
            self.counts["links_sent"] += 1

    def _link_moved(self, j: int, sent: SE2 | None, now: SE2 | None) -> bool:
        if sent is None or now is None:
            return (sent is None) != (now is None)
        return not within(sent, now, self.mergers[j].vertices.xy.mean(axis=0), links.LINK_MOVE_M, links.LINK_TURN_RAD)

    def _refresh_grid(self, now_us: int) -> bool:
        """The profile grid and own map for the merge's checks, rendered again every
        grid_period_s if the robot built a vertex since. True if rendered now."""
        p = self.s.params
        n_own = len(self.builder.vertices)
        if n_own == 0:
            return False
        if self._grid_us is not None and (now_us - self._grid_us < self.pp.grid_period_s * 1e6
                                          or n_own == self._grid_vertices):
            return False
        state, r0, c0 = self.s.local_map.whole_state()
        range_max = float(self.s.last_scan()[3].range_max_m)
        self._grid = ProfileGrid.of_map(state, r0, c0, p.resolution_m, range_max, self.pp)
        visited = self.s.topo.positions()
        own_xy = self._own_vertices().xy
        self._own_map = OwnMap(state, r0, c0, p.resolution_m, np.vstack([visited, own_xy]), range_max)
        self._grid_us, self._grid_vertices = now_us, n_own
        self._grid_token += 1
        self.counts["grid_renders"] += 1
        return True

    def _team_in_own_frame(self) -> tuple[dict[int, np.ndarray], dict[int, list[tuple[int, int]]]]:
        """Merged teammates' vertices as received so far, in the own frame, and their keys."""
        xy, keys = {}, {}
        for j, T in sorted(self._merged.items()):
            vs = self.mergers[j].vertices
            xy[j] = T.apply(vs.xy) if len(vs) else np.zeros((0, 2))
            keys[j] = list(vs.keys)
        return xy, keys

    def _refresh_team(self) -> None:
        """Merged teammates' vertices in the own frame for planning until the next merge run
        (Algorithm 1's `others`, eq. (1))."""
        self._team_xy, self._team_keys = self._team_in_own_frame()
        self._merged_places = [Place(v.owner, v.vid, float(p[0]), float(p[1]), v.desc)
                               for j in self._team_xy
                               for v, p in zip(self.mergers[j].vertices.vertices, self._team_xy[j])]

    # --- directions -------------------------------------------------------------------
    def _open_directions(self) -> list[Direction]:
        """Every open direction of the own vertices and of merged teammates' vertices, in the
        own frame, not given up here; in the order of vertex key and sector."""
        out: list[Direction] = []
        for v in self.builder.vertices:
            left = self.book.remaining(v.key)
            if not left:
                continue
            for c in self.builder.clusters.get(v.vid, ()):
                if sector_class(left, c.sector) and (v.key, c.sector) not in self._given_up:
                    out.append(Direction(v.key, c.sector, c.x_m, c.y_m, v.x_m, v.y_m, True))
        for j, T in sorted(self._merged.items()):
            vs = self.mergers[j].vertices
            for v, (vx, vy) in zip(vs.vertices, self._team_xy[j]):
                left = self.book.remaining(v.key)
                if not left:
                    continue
                ks, pts = dirs.direction_points(v.x_m, v.y_m, left, self.pp)
                pts = T.apply(pts)
                for k, (px, py) in zip(ks.tolist(), pts.tolist()):
                    if (v.key, k) not in self._given_up:
                        out.append(Direction(v.key, int(k), px, py, float(vx), float(vy), False))
        return out

    def _clear(self, key: tuple[int, int], mask: int, announce: bool = True) -> None:
        self.book.clear(key, mask)
        if not announce:
            return
        said = self._said_clear.get(key, 0)
        if said | mask == said:
            return
        said |= mask
        self._said_clear[key] = said
        # One record per vertex in the queue: a newer mask (a superset) replaces a queued one.
        self._send("mrud", {"sender_id": self.me, "owner_id": key[0], "vertex_id": key[1], "clear_mask": said},
                   PRIORITY_INFO, key=("mrud", key))
        self.counts["ud_records_sent"] += 1

    def _update_directions(self, view: PlanningView, open_dirs: list[Direction]) -> list[Direction]:
        """III-E: clear the directions explored now; the ones left. A direction is explored
        when the robot came within explored_radius_m of its point, or when its point is a
        window cell the robot knows (its own direction, or a known cell) with no reachable
        frontier cell that close."""
        lm = self.s.local_map
        r = self.pp.explored_radius_m
        unknown = view.sight == kernels.UNKNOWN
        reached = [math.hypot(d.x_m - view.x_m, d.y_m - view.y_m) <= r for d in open_dirs]
        judged = {}                          # direction index -> its window cell
        for n, d in enumerate(open_dirs):
            if not reached[n]:
                i, j = lm.cell_of(d.x_m, d.y_m)
                # A window cell away from the edge: the map around it is what the robot knows.
                if 2 <= i < lm.n - 2 and 2 <= j < lm.n - 2 and (d.own or not unknown[i, j]):
                    judged[n] = (i, j)
        no_frontier_near = self._no_frontier_near(view, list(judged.values()), r) if judged else []
        gone = reached[:]
        for n, far in zip(judged, no_frontier_near):
            gone[n] = far
        left, cleared = [], {}
        for n, d in enumerate(open_dirs):
            if gone[n]:
                cleared[d.key] = cleared.get(d.key, 0) | (1 << d.sector)
            else:
                left.append(d)
        for key, mask in sorted(cleared.items()):
            self.counts["directions_explored"] += bin(mask).count("1")
            self._clear(key, mask)
        return left

    def _no_frontier_near(self, view: PlanningView, cells: list[tuple[int, int]], radius_m: float) -> list[bool]:
        """For each window cell: no frontier cell the robot can reach (4-connected free
        space from where it stands) lies within radius_m of it."""
        lm, res = self.s.local_map, self.s.params.resolution_m
        free = view.sight == kernels.FREE
        pad = np.pad(view.sight == kernels.UNKNOWN, 1, constant_values=True)
        frontier = free & (pad[:-2, 1:-1] | pad[2:, 1:-1] | pad[1:-1, :-2] | pad[1:-1, 2:])
        ri, rj = lm.cell_of(view.x_m, view.y_m)
        start = nearest_traversable(free, ri, rj, 5) if lm.in_window(ri, rj) else None
        if start is None:
            return [True] * len(cells)
        labels, _ = ndimage.label(free, structure=_FOUR)
        frontier &= labels == labels[start]
        if not frontier.any():
            return [True] * len(cells)
        # Distances at these few cells only (a distance transform of the whole window gives
        # the same numbers, exact square roots of whole numbers, at every cell).
        dist_cells, _ = cKDTree(np.argwhere(frontier).astype(np.float64)).query(np.array(cells, dtype=np.float64))
        return [bool(d * res > radius_m) for d in dist_cells]

    def _eq1(self, xy: np.ndarray) -> np.ndarray:
        """Eq. (1) for points xy (n, 2) in the own frame: w d(c_own, f) + (1 - w)/m sum_j
        d(c_j, f) over the m merged teammates (w alone, the paper's III-D1, before any merge)."""
        w = self.pp.w
        own = self._own_vertices().xy
        c = own.mean(axis=0) if len(own) else np.zeros(2)
        s = np.hypot(xy[:, 0] - c[0], xy[:, 1] - c[1])
        centres = [xy_j.mean(axis=0) for xy_j in self._team_xy.values() if len(xy_j)]
        if not centres:
            return s
        team = sum(np.hypot(xy[:, 0] - cj[0], xy[:, 1] - cj[1]) for cj in centres) / len(centres)
        return w * s + (1.0 - w) * team

    def _snap(self, d: Direction, view: PlanningView) -> tuple[float, float] | None:
        """Where to head for a direction: the reachable cell nearest its point (SNAP_M at
        most) when the point is in the window, the point itself beyond it (routed along
        the own places); None when the window shows no way there."""
        lm = self.s.local_map
        i, j = lm.cell_of(d.x_m, d.y_m)
        if not lm.in_window(i, j) or view.reachable is None:
            return d.x_m, d.y_m
        cell = nearest_traversable(view.reachable, i, j, int(round(SNAP_M / self.s.params.resolution_m)))
        return None if cell is None else lm.center_of(*cell)

    # --- the planning stage -----------------------------------------------------------
    def filter_waypoints(self, view: PlanningView) -> None:
        """Own waypoints a merged teammate evidently saw are left to it: one of its vertices
        within team_near_m in line of sight, and none of its open directions that close."""
        near_m = self.pp.team_near_m
        items = self.s.waypoints.items
        if near_m <= 0 or not items or not self._team_xy:
            return
        team = np.vstack(list(self._team_xy.values()))
        if not len(team):
            return
        open_pts = np.array([(d.x_m, d.y_m) for d in self._open_directions() if not d.own]).reshape(-1, 2)
        lm = self.s.local_map
        keep = []
        for w in items:
            d2 = (team[:, 0] - w.x_m) ** 2 + (team[:, 1] - w.y_m) ** 2
            near = np.flatnonzero(d2 <= near_m * near_m)
            left = False
            if near.size and not (len(open_pts) and (np.hypot(open_pts[:, 0] - w.x_m, open_pts[:, 1] - w.y_m)
                                                     <= near_m).any()):
                wij, w_in = lm.cells_of(np.array([[w.x_m, w.y_m]]))
                vij, v_in = lm.cells_of(team[near])
                if w_in[0] and v_in.any():
                    vij = vij[v_in]
                    n = len(vij)
                    left = bool(lines_of_sight(view.sight, np.full(n, wij[0, 0]), np.full(n, wij[0, 1]),
                                               vij[:, 0], vij[:, 1]).any())
            if left:
                self.counts["waypoints_left_to_team"] += 1
            else:
                keep.append(w)
        items[:] = keep

    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        open_dirs = self._update_directions(view, self._open_directions())
        self._offered = {}
        out: list[Candidate] = []
        goal = self._goal
        if goal is not None and self.s.waypoints.is_banned(goal.x_m, goal.y_m):
            goal, self._regoal = None, True
        if goal is not None and not self._regoal:
            out.append(Candidate(goal.x_m, goal.y_m, 0.0, True, rank=0))
        else:
            self._goal = None
            self._regoal = False
            out += self._direction_candidates(view, open_dirs)
        for c in own:
            c.rank = 1
            out.append(c)
        cost_along_graph(view, out)
        return out

    def _direction_candidates(self, view: PlanningView, open_dirs: list[Direction]) -> list[Candidate]:
        """The best direction (eq. 1) of the current vertex, ranked first; without one there,
        the best direction of every vertex that has one, ranked with the own waypoints."""
        by_vertex: dict[tuple[int, int], list[tuple[Direction, tuple[float, float]]]] = {}
        for d in open_dirs:
            at = self._snap(d, view)
            k = (d.key, d.sector)
            if at is None:
                self._unreachable[k] = self._unreachable.get(k, 0) + 1
                if self._unreachable[k] >= UNREACHABLE_CYCLES:
                    self._given_up.add(k)
                    self.counts["directions_given_up"] += 1
                continue
            if self.s.waypoints.is_banned(*at):
                self._given_up.add(k)
                self.counts["directions_given_up"] += 1
                continue
            self._unreachable.pop(k, None)
            by_vertex.setdefault(d.key, []).append((d, at))
        out = []
        current = self.builder.last
        groups = [by_vertex[current]] if current in by_vertex else [by_vertex[k] for k in sorted(by_vertex)]
        rank = 0 if current in by_vertex else 1
        for group in groups:
            pts = np.array([[d.x_m, d.y_m] for d, _ in group])
            best = int(np.argmax(self._eq1(pts)))            # first of the best: lowest sector
            d, (x, y) = group[best]
            self._offered[(x, y)] = d
            out.append(Candidate(x, y, 0.0, True, rank=rank))
        return out

    def after_plan(self, pose: OdometrySample, now_us: int) -> None:
        """The robot heads for a direction offered this cycle: it is the goal now, deleted
        from its vertex's list and announced (III-E)."""
        t = self.s.current_target()
        if t is None or self._goal is not None:
            return
        d = self._offered.get((t.x_m, t.y_m))
        if d is None:
            return
        self._goal = Goal(d.key, d.sector, t.x_m, t.y_m)
        self.counts["goals_taken"] += 1
        self._clear(d.key, 1 << d.sector)

    def on_target_outcome(self, target: Target, outcome: str) -> None:
        g = self._goal
        if g is not None and (target.x_m, target.y_m) == (g.x_m, g.y_m):
            self._goal, self._regoal = None, True     # III-D3 (b): the goal ended

    def wake_up(self, now_us: int) -> bool:
        """A robot that stopped goes on when a merged teammate's vertex has an open direction
        it has not given up (A17: the exploration ends when no vertex in its map has one),
        asked at most every known_map_refresh_s."""
        if now_us - self._woken_us < self.s.params.known_map_refresh_s * 1e6:
            return False
        self._woken_us = now_us
        if any(not d.own for d in self._open_directions()):
            self._regoal = True
            self.counts["wake_ups"] += 1
            return True
        return False

    def has_news(self) -> bool:
        return any(self.s.queued(t) for t in _OWN_TYPES)

    # --- for the host -----------------------------------------------------------------
    def frame_merges(self) -> dict[int, SE2]:
        """Teammate -> T_own<-teammate, for the teammates merged now (direct merges weighed
        against teammates' links, and merges by composition)."""
        return dict(self._merged)

    def teammate_vertex_xy(self, j: int) -> np.ndarray:
        """Teammate j's vertices as received, in j's own frame (n, 2)."""
        m = self.mergers.get(j)
        return m.vertices.xy if m is not None else np.zeros((0, 2))

    def own_vertex_xy(self) -> np.ndarray:
        return self._own_vertices().xy

    def stats(self) -> dict[str, int]:
        ms = self.mergers.values()
        return {**self.counts, "vertices_built": len(self.builder.vertices),
                "teammates_heard": len(self.mergers), "teammates_merged": len(self._merged),
                "merges": sum(m.merges for m in ms), "unmerges": sum(m.unmerges for m in ms),
                "merge_corrections": sum(m.corrections for m in ms),
                "open_directions": len(self.book.open_keys())}

    def drawables(self) -> dict:
        """Own vertices and every merged teammate's received so far (also those heard since
        the last merge run), in the own frame."""
        own = self._own_vertices()
        team_xy, team_keys = self._team_in_own_frame()
        xy = [own.xy] + [team_xy[j] for j in sorted(team_xy)]
        keys = list(own.keys) + [k for j in sorted(team_keys) for k in team_keys[j]]
        pts = np.vstack(xy) if keys else np.zeros((0, 2))
        where = {k: pts[n] for n, k in enumerate(keys)}
        segs = [(where[a], where[b]) for a, b in sorted(self.edges) if a in where and b in where]
        return {"title": "MR-TopoMap: each robot's own and merged teammates' vertices (red rings: open directions)",
                "points": pts, "segments": np.array(segs).reshape(-1, 2, 2),
                "highlight": np.array([self.book.remaining(k) != 0 for k in keys], bool), "what": "vertices"}

"""The robot's dense local map: a log-odds window of fixed size that follows the robot.

Planning works on the window only, so its cost is fixed by the window size, whatever the
area explored. What leaves the window is paged out to `TilePager` and paged back in when
the robot returns: a place comes back exactly as it was left, instead of looking unexplored
again. Scans binned to fixed world bearings (`BinnedScan`) live here too: folding one in
(a dense baseline's keyframe) is a window operation, and a stalled robot reads its last scan
so.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.services.body_fit import PlanningFits


class TilePager:
    """The log-odds of every place the window has left, in square tiles of TILE_CELLS cells
    on a fixed grid (global cell coordinates). Memory grows with the area the window has
    covered, 16 KiB per tile (6.4 m x 6.4 m at 0.1 m), and only tiles holding something are
    kept. Restoring places from the scans taken there (one per vertex, as before) left out
    what the scans in between had seen: places restored that way grew frontiers in explored
    ground, and robots went back to them (a robot alone on maze_a, seed 0, drove 6 km)."""

    TILE_CELLS = 64

    def __init__(self) -> None:
        self._tiles: dict[tuple[int, int], np.ndarray] = {}

    @property
    def nbytes(self) -> int:
        return sum(t.nbytes for t in self._tiles.values())

    def _overlapping(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int):
        """(tile row, tile col, global row range, global col range) of each tile cut by the
        global cell rectangle [r_lo, r_hi) x [c_lo, c_hi)."""
        t = self.TILE_CELLS
        for ti in range(r_lo // t, (r_hi - 1) // t + 1):
            for tj in range(c_lo // t, (c_hi - 1) // t + 1):
                yield ti, tj, (max(r_lo, ti * t), min(r_hi, (ti + 1) * t)), (max(c_lo, tj * t), min(c_hi, (tj + 1) * t))

    def save(self, window: np.ndarray, row0: int, col0: int) -> None:
        """Page out the whole window (anchored at global cell row0, col0)."""
        n_r, n_c = window.shape
        t = self.TILE_CELLS
        for ti, tj, (g0, g1), (h0, h1) in self._overlapping(row0, row0 + n_r, col0, col0 + n_c):
            part = window[g0 - row0:g1 - row0, h0 - col0:h1 - col0]
            tile = self._tiles.get((ti, tj))
            if tile is None:
                if not part.any():
                    continue  # nothing known there: no tile
                tile = self._tiles[(ti, tj)] = np.zeros((t, t), window.dtype)
            tile[g0 - ti * t:g1 - ti * t, h0 - tj * t:h1 - tj * t] = part

    def load(self, window: np.ndarray, row0: int, col0: int, region: tuple[int, int, int, int]) -> None:
        """Page in the window cells [r_lo, r_hi) x [c_lo, c_hi) (window indices); cells of
        tiles never paged out are left as they are (unknown: 0)."""
        r_lo, r_hi, c_lo, c_hi = region
        if r_lo >= r_hi or c_lo >= c_hi:
            return
        t = self.TILE_CELLS
        for ti, tj, (g0, g1), (h0, h1) in self._overlapping(row0 + r_lo, row0 + r_hi, col0 + c_lo, col0 + c_hi):
            tile = self._tiles.get((ti, tj))
            if tile is not None:
                window[g0 - row0:g1 - row0, h0 - col0:h1 - col0] = tile[g0 - ti * t:g1 - ti * t, h0 - tj * t:h1 - tj * t]

    def tile_keys(self):
        """(tile row, tile col) of every tile held."""
        return self._tiles.keys()

    def tiles_within(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int, dtype) -> list[tuple[np.ndarray, int, int]]:
        """(tile, its global row0, col0) for every tile cut by the global cell rectangle,
        created if missing, for folding a scan into places outside the window."""
        t = self.TILE_CELLS
        out = []
        for ti, tj, _, _ in self._overlapping(r_lo, r_hi, c_lo, c_hi):
            tile = self._tiles.get((ti, tj))
            if tile is None:
                tile = self._tiles[(ti, tj)] = np.zeros((t, t), dtype)
            out.append((tile, ti * t, tj * t))
        return out


class BinnedScan(NamedTuple):
    """A 360-degree scan in the world frame: bin b covers the bearings within half a bin of
    bearing0_rad + b * 2 pi / len(ranges_m); a range of 0 means no beam fell in the bin."""

    x_m: float
    y_m: float
    bearing0_rad: float
    ranges_m: np.ndarray
    range_max_m: float


def bin_scan(x_m: float, y_m: float, yaw_rad: float, angle_min_rad: float, angle_increment_rad: float,
             ranges_m: np.ndarray, range_max_m: float, bins: int) -> BinnedScan:
    """A robot-frame scan in `bins` world-frame bins (shortest beam per bin), the first bin
    centred on the first beam. The bins follow the beams rather than fixed world bearings:
    with as many bins as beams each beam keeps its own bearing, so a teammate folding in the
    keyframe gets the scan that was taken there. Bins on fixed bearings moved every beam by
    up to half a bin; along a wall seen at a grazing angle that shifts the range enough to
    clear cells behind the wall."""
    bearing0 = (yaw_rad + angle_min_rad) % (2 * math.pi)
    offsets = angle_increment_rad * np.arange(len(ranges_m))
    idx = np.floor((offsets % (2 * math.pi)) / (2 * math.pi / bins) + 0.5).astype(np.int64) % bins
    out = np.full(bins, np.inf)
    np.minimum.at(out, idx, ranges_m.astype(np.float64))
    out[~np.isfinite(out)] = 0.0
    return BinnedScan(float(x_m), float(y_m), float(bearing0), out, float(range_max_m))


def something_within(scan: BinnedScan, yaw_rad: float, reach_m: float) -> bool:
    """Whether a binned scan shows a return within reach_m in the half-plane ahead of the
    heading yaw_rad."""
    bins = len(scan.ranges_m)
    bearing = scan.bearing0_rad + np.arange(bins) * (2 * math.pi / bins)
    r = np.asarray(scan.ranges_m)
    return bool(((r > 0.0) & (r <= reach_m) & (np.cos(bearing - yaw_rad) > 0.0)).any())


@dataclass
class MapLayers:
    """What planning needs, derived from the log-odds once per planning cycle."""

    state: np.ndarray          # UNKNOWN / FREE / OCCUPIED per cell
    sight: np.ndarray          # state with unknown cells next to walls closed, for ray casting
    traversable: np.ndarray    # bool: known free, and the body fits somewhere in the cell
    cell_cost: np.ndarray      # >= 1: a cost decaying away from walls and unknown
    clearance_m: np.ndarray    # float32: room from the best point of the cell to the expected wall faces
    standing: np.ndarray       # int8: index into kernels.SUBCELL_OFFSETS of the cell's best point


def grid_cells_of(xy: np.ndarray, row0: int, col0: int, shape: tuple[int, ...],
                  resolution_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Cells (rows of i, j) of world points (rows of x, y) on a grid whose cell (0, 0) is the
    global cell (row0, col0), and which of them lie on the grid's shape."""
    xy = np.asarray(xy, np.float64).reshape(-1, 2)
    ij = np.stack([np.floor(xy[:, 1] / resolution_m).astype(np.int64) - row0,
                   np.floor(xy[:, 0] / resolution_m).astype(np.int64) - col0], axis=1)
    return ij, (ij >= 0).all(axis=1) & (ij[:, 0] < shape[0]) & (ij[:, 1] < shape[1])


def close_wall_gaps(state: np.ndarray) -> np.ndarray:
    """Unknown cells touching a wall cell count as wall for line of sight. Far walls are hit
    by beams more than a cell apart, so their occupied cells have unknown gaps; rays slipping
    through them would count the never-observable rock behind as information."""
    occ = state == kernels.OCCUPIED
    grown = occ.copy()
    grown[1:, :] |= occ[:-1, :]
    grown[:-1, :] |= occ[1:, :]
    grown[:, 1:] |= occ[:, :-1]
    grown[:, :-1] |= occ[:, 1:]
    grown[1:, 1:] |= occ[:-1, :-1]
    grown[1:, :-1] |= occ[:-1, 1:]
    grown[:-1, 1:] |= occ[1:, :-1]
    grown[:-1, :-1] |= occ[1:, 1:]
    out = state.copy()
    out[grown & (state == kernels.UNKNOWN)] = kernels.OCCUPIED
    return out


# Bounded memory for mark_passed: 10 cells a metre, so 2 km of passages.
MAX_PASSED_CELLS = 20_000
# The trail (mark_trail): a point a metre, at most 20 km of them.
TRAIL_SPACING_M = 1.0
MAX_TRAIL_POINTS = 20_000
# The body's recent path (mark_trail), finer: a point every 5 cm over the last 5 m. An
# obstacle felt where the body has just been is a mark drawn askew, not an obstacle.
RECENT_SPACING_M = 0.05
RECENT_PATH_M = 5.0


class TeamView(Protocol):
    """What teammates told a robot about the places they saw (a scheme that shares maps)."""

    def fill_unknown(self, state: np.ndarray, row0: int, col0: int) -> None:
        """Fill the UNKNOWN cells of a state grid anchored at global cell (row0, col0) with
        what teammates saw there."""

    def extent(self) -> tuple[int, int, int, int] | None:
        """The global cells (row_lo, col_lo, row_hi, col_hi), ends excluded, that teammates
        told anything about; None if nothing."""


class LocalMap:
    MAX_BUMP_CELLS = 7 * 64
    def __init__(self, params: ExplorationParams, x_m: float, y_m: float) -> None:
        self.p = params
        self.n = params.window_cells
        self.logodds = np.zeros((self.n, self.n), np.float32)
        self.pager = TilePager()
        self.row0, self.col0 = self._anchor_for(x_m, y_m)
        self.bumps: list[tuple[float, float]] = []   # obstacles felt, not seen (mark_obstacle_ahead)
        # Global cells the body's centre has been through where the map shows too little room
        # (mark_passed): a gap the robot drove through is one it fits through.
        self.passed: set[tuple[int, int]] = set()
        self._last_passed: tuple[int, int] | None = None
        self._passed_cells = np.zeros((0, 2), np.int64)   # self.passed as an array, for layers()
        self._trail: list[tuple[float, float]] = []         # where the body's centre has been (mark_trail)
        self._recent: deque[tuple[float, float]] = deque(maxlen=int(round(RECENT_PATH_M / RECENT_SPACING_M)))
        self._fits = PlanningFits(params)
        # The passages of the last ordinary layers (in_passage_at) and their anchor.
        self._passages = np.zeros((0, 0), bool)
        self._passages_anchor = (0, 0)
        # What teammates told this robot about places it has not observed itself, set by a
        # scheme that shares maps. Planning sees it; the log-odds (this robot's own
        # observations) never do.
        self.team: TeamView | None = None

    # --- geometry -------------------------------------------------------------------
    def _anchor_for(self, x_m: float, y_m: float) -> tuple[int, int]:
        res = self.p.resolution_m
        return (int(math.floor(y_m / res)) - self.n // 2, int(math.floor(x_m / res)) - self.n // 2)

    def cell_of(self, x_m: float, y_m: float) -> tuple[int, int]:
        res = self.p.resolution_m
        return int(math.floor(y_m / res)) - self.row0, int(math.floor(x_m / res)) - self.col0

    def center_of(self, i: int, j: int) -> tuple[float, float]:
        res = self.p.resolution_m
        return (self.col0 + j + 0.5) * res, (self.row0 + i + 0.5) * res

    def in_window(self, i: int, j: int) -> bool:
        return 0 <= i < self.n and 0 <= j < self.n

    def cells_of(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Window cells (rows of i, j) of world points (rows of x, y), and which of them
        are inside the window."""
        return grid_cells_of(xy, self.row0, self.col0, (self.n, self.n), self.p.resolution_m)

    def contains(self, x_m: float, y_m: float, margin_cells: int = 0) -> bool:
        i, j = self.cell_of(x_m, y_m)
        return margin_cells <= i < self.n - margin_cells and margin_cells <= j < self.n - margin_cells

    def bounds_m(self) -> tuple[float, float, float, float]:
        res = self.p.resolution_m
        return (self.col0 * res, (self.col0 + self.n) * res, self.row0 * res, (self.row0 + self.n) * res)

    # --- updates ------------------------------------------------------------------
    def integrate_keyframe(self, scan: BinnedScan) -> None:
        """Fold a peer's keyframe (dense-map sharing) into the window and into the paged-out
        places it reaches, once: the window is paged out whole before it moves, so the tile
        cells it covers now are overwritten then, and those outside it are what comes back."""
        res = self.p.resolution_m
        fold = (scan.x_m, scan.y_m, scan.bearing0_rad, 2 * math.pi / len(scan.ranges_m),
                np.ascontiguousarray(scan.ranges_m, np.float64), scan.range_max_m)
        self._fill(*fold, (0, self.n, 0, self.n))
        reach_cells = int(math.ceil(scan.range_max_m / res)) + 2
        ci, cj = int(math.floor(scan.y_m / res)), int(math.floor(scan.x_m / res))
        r_lo, r_hi, c_lo, c_hi = ci - reach_cells, ci + reach_cells + 1, cj - reach_cells, cj + reach_cells + 1
        if self.row0 <= r_lo and r_hi <= self.row0 + self.n and self.col0 <= c_lo and c_hi <= self.col0 + self.n:
            return  # all inside the window
        for tile, t_row0, t_col0 in self.pager.tiles_within(r_lo, r_hi, c_lo, c_hi, self.logodds.dtype):
            t = tile.shape[0]
            self._fill(*fold, (0, t, 0, t), grid=(tile, t_row0, t_col0))

    def mark_obstacle_ahead(self, x_m: float, y_m: float, yaw_rad: float, distance_m: float) -> None:
        """Remember an obstacle just ahead of the robot (a short arc across its heading) that
        the LiDAR does not show. Kept apart from the log-odds, so later scans that see free
        space there cannot erase it and send the robot into the same spot again. Points of
        the arc the body has covered on its recent path (body_covers) are left out: the body
        was there, so nothing is; an arc drawn across the way the robot came, after it
        turned at a corner, would shut it in."""
        offsets = np.linspace(-0.6, 0.6, 7)
        arc = np.column_stack((x_m + distance_m * np.cos(yaw_rad + offsets), y_m + distance_m * np.sin(yaw_rad + offsets)))
        covered = self.body_covers(arc)
        self.bumps.extend((float(bx), float(by)) for (bx, by), c in zip(arc, covered) if not c)
        del self.bumps[:-self.MAX_BUMP_CELLS]  # bounded memory: the oldest are forgotten first

    def body_covers(self, xy_m: np.ndarray) -> np.ndarray:
        """Per point (n, 2, metres): did the body cover it on its recent path (mark_trail's
        last RECENT_PATH_M), its centre within the body's radius less half a cell (the
        pose's error, a mark's cell) of it?"""
        xy_m = np.asarray(xy_m, np.float64).reshape(-1, 2)
        if not self._recent or not len(xy_m):
            return np.zeros(len(xy_m), bool)
        path = np.array(self._recent, np.float64)
        d2 = ((xy_m[:, None, :] - path[None, :, :]) ** 2).sum(axis=2).min(axis=1)
        reach_m = self.p.robot_radius_m - 0.5 * self.p.resolution_m
        return d2 <= reach_m * reach_m

    def forget_bumps(self) -> None:
        """Forget every obstacle mark_obstacle_ahead remembered."""
        self.bumps.clear()

    def mark_trail(self, x_m: float, y_m: float) -> None:
        """The body's centre is here now: keep a point every TRAIL_SPACING_M of the way, and
        every RECENT_SPACING_M of its last RECENT_PATH_M."""
        recent = self._recent
        if not recent or math.hypot(x_m - recent[-1][0], y_m - recent[-1][1]) >= RECENT_SPACING_M:
            recent.append((x_m, y_m))
        if len(self._trail) < MAX_TRAIL_POINTS and (
                not self._trail or math.hypot(x_m - self._trail[-1][0], y_m - self._trail[-1][1]) >= TRAIL_SPACING_M):
            self._trail.append((x_m, y_m))

    def trail(self) -> np.ndarray:
        """Where the body's centre has been (mark_trail), (n, 2) in metres."""
        return np.array(self._trail, np.float64).reshape(-1, 2)

    def in_passage_at(self, x_m: float, y_m: float) -> bool:
        """Is this point on a passage of the last ordinary layers: a tight passage
        (PlanningFits), or a cell that leaves the body less room than slow_clearance_m (a
        door, a gap in clutter)? Later scans may draw such a gap narrower than the body, so
        the cells driven through there are remembered (mark_passed)."""
        row = int(math.floor(y_m / self.p.resolution_m)) - self._passages_anchor[0]
        col = int(math.floor(x_m / self.p.resolution_m)) - self._passages_anchor[1]
        return 0 <= row < self._passages.shape[0] and 0 <= col < self._passages.shape[1] \
            and bool(self._passages[row, col])

    def mark_passed(self, x_m: float, y_m: float) -> None:
        """The body's centre is here now, on a passage (in_passage_at) or a cell the map shows
        too narrow even for a tight one (a tight path after a recovery): remember the cell,
        as a 4-connected chain with the last one marked, so that later plans may route
        through the same gap."""
        row = int(math.floor(y_m / self.p.resolution_m))
        col = int(math.floor(x_m / self.p.resolution_m))
        last = self._last_passed
        if last is not None and abs(row - last[0]) == 1 and abs(col - last[1]) == 1:
            self.passed.add((last[0], col))          # a diagonal step: keep the chain 4-connected
        if len(self.passed) < MAX_PASSED_CELLS:
            self.passed.add((row, col))
        self._last_passed = (row, col)

    def _fill(self, px, py, bin0, binw, ranges, range_max, region, grid=None) -> None:
        """Fold a scan into `region` of the window, or of grid = (log-odds array, its global
        row0, col0), a paged-out tile."""
        p = self.p
        logodds, row0, col0 = grid if grid is not None else (self.logodds, self.row0, self.col0)
        kernels.polar_fill(logodds, row0, col0, p.resolution_m, px, py, bin0, binw,
                           ranges, range_max, p.logodds_hit, p.logodds_miss, p.logodds_min,
                           p.logodds_max, *region)

    def integrate_scan(self, x_m, y_m, yaw_rad, angle_min_rad, angle_increment_rad, ranges_m, range_max_m) -> None:
        ranges = np.ascontiguousarray(ranges_m, dtype=np.float64)
        self._fill(x_m, y_m, yaw_rad + angle_min_rad, angle_increment_rad, ranges, range_max_m,
                   (0, self.n, 0, self.n))

    def follow(self, x_m: float, y_m: float) -> bool:
        """Re-anchor the window on the robot once it has drifted off centre, paging out
        what it held and paging in the newly exposed cells. Returns True if the window moved."""
        cx, cy = self.center_of(self.n // 2, self.n // 2)
        if max(abs(x_m - cx), abs(y_m - cy)) < self.p.recenter_distance_m:
            return False
        row0, col0 = self._anchor_for(x_m, y_m)
        di, dj = row0 - self.row0, col0 - self.col0
        self.pager.save(self.logodds, self.row0, self.col0)
        shifted = np.zeros_like(self.logodds)
        n = self.n
        src_i = slice(max(di, 0), min(n + di, n))
        dst_i = slice(max(-di, 0), min(n - di, n))
        src_j = slice(max(dj, 0), min(n + dj, n))
        dst_j = slice(max(-dj, 0), min(n - dj, n))
        shifted[dst_i, dst_j] = self.logodds[src_i, src_j]
        self.logodds = shifted
        self.row0, self.col0 = row0, col0
        # Newly exposed cells: the rows band and the columns band the shift uncovered.
        regions = []
        if di > 0:
            regions.append((max(n - di, 0), n, 0, n))
        elif di < 0:
            regions.append((0, min(-di, n), 0, n))
        if dj > 0:
            regions.append((0, n, max(n - dj, 0), n))
        elif dj < 0:
            regions.append((0, n, 0, min(-dj, n)))
        for region in regions:
            self.pager.load(self.logodds, self.row0, self.col0, region)
        return True

    # --- derived layers -------------------------------------------------------------
    def state_of(self, i0: int, i1: int, j0: int, j1: int) -> np.ndarray:
        """UNKNOWN / FREE / OCCUPIED of the window cells [i0, i1) x [j0, j1), from what the
        LiDAR saw alone (no bumps)."""
        p = self.p
        return kernels.classify(np.ascontiguousarray(self.logodds[i0:i1, j0:j1]), p.logodds_occupied, p.logodds_free)

    def layers(self, tight: bool = False) -> MapLayers:
        """Ordinary layers (tight passages at a cost), or tight: a retry after a recovery,
        with the wall faces at their cells' centres (the most room there can be) everywhere
        (PlanningFits)."""
        p = self.p
        state = kernels.classify(self.logodds, p.logodds_occupied, p.logodds_free)
        self._mark_bumps(state, self.row0, self.col0)
        if self.team is not None:
            self.team.fill_unknown(state, self.row0, self.col0)
        if tight:
            fit = self._fits.retry(state, self.row0, self.col0)
        else:
            fit, narrow = self._fits.ordinary(state, self.row0, self.col0)
            short_of_room = fit.clearance_m - p.robot_radius_m < p.slow_clearance_m
            self._passages = narrow | (fit.traversable & short_of_room)
            self._passages_anchor = (self.row0, self.col0)
        self.open_passed(fit.traversable, state, self.row0, self.col0)
        return MapLayers(state=state, sight=close_wall_gaps(state), traversable=fit.traversable,
                         cell_cost=fit.cell_cost, clearance_m=fit.clearance_m, standing=fit.standing)

    def whole_state(self, felt: bool = True) -> tuple[np.ndarray, int, int]:
        """The state (UNKNOWN / FREE / OCCUPIED, bumps as walls unless not felt) of
        everything mapped: the window over every paged-out tile, on their bounding box; and
        the box's global (row0, col0)."""
        p = self.p
        t = TilePager.TILE_CELLS
        keys = list(self.pager.tile_keys())
        r_lo = min([self.row0] + [ti * t for ti, _ in keys])
        c_lo = min([self.col0] + [tj * t for _, tj in keys])
        r_hi = max([self.row0 + self.n] + [(ti + 1) * t for ti, _ in keys])
        c_hi = max([self.col0 + self.n] + [(tj + 1) * t for _, tj in keys])
        extent = self.team.extent() if self.team is not None else None
        if extent is not None:
            # With room beyond it for a frontier at its edge to show what it hides.
            pad = int(math.ceil(p.d_cam_m / p.resolution_m))
            r_lo, c_lo = min(r_lo, extent[0] - pad), min(c_lo, extent[1] - pad)
            r_hi, c_hi = max(r_hi, extent[2] + pad), max(c_hi, extent[3] + pad)
        logodds = np.zeros((r_hi - r_lo, c_hi - c_lo), self.logodds.dtype)
        self.pager.load(logodds, r_lo, c_lo, (0, r_hi - r_lo, 0, c_hi - c_lo))
        logodds[self.row0 - r_lo:self.row0 - r_lo + self.n, self.col0 - c_lo:self.col0 - c_lo + self.n] = self.logodds
        state = kernels.classify(logodds, p.logodds_occupied, p.logodds_free)
        if felt:
            self._mark_bumps(state, r_lo, c_lo)
        if self.team is not None:
            self.team.fill_unknown(state, r_lo, c_lo)
        return state, r_lo, c_lo

    def _mark_bumps(self, state: np.ndarray, row0: int, col0: int) -> None:
        """Obstacles felt (mark_obstacle_ahead) as walls in a state grid anchored at global
        cell (row0, col0)."""
        res = self.p.resolution_m
        n_r, n_c = state.shape
        for bx, by in self.bumps:
            i, j = int(math.floor(by / res)) - row0, int(math.floor(bx / res)) - col0
            if 0 <= i < n_r and 0 <= j < n_c:
                state[i, j] = kernels.OCCUPIED

    def open_passed(self, traversable: np.ndarray, state: np.ndarray, row0: int, col0: int) -> None:
        """Cells the body has been through (mark_passed) are traversable while they read
        free, in grids anchored at global cell (row0, col0)."""
        if not self.passed:
            return
        if len(self._passed_cells) != len(self.passed):       # the set only grows
            self._passed_cells = np.array(sorted(self.passed), np.int64).reshape(-1, 2)
        cells = self._passed_cells - (row0, col0)
        inside = (cells >= 0).all(axis=1) & (cells < traversable.shape).all(axis=1)
        i, j = cells[inside, 0], cells[inside, 1]
        free = state[i, j] == kernels.FREE
        traversable[i[free], j[free]] = True

"""Exploration waypoints scored by expected information (Bayer & Faigl IV-A, eq. 3).

e(nu) = log2(a + 1) * |{xi : ||nu - xi|| < d_cam, observable(nu, xi), xi not yet seen}|.
Waypoints are reachable cells at least w_cl,radius apart with e >= e_min. The set W is kept
across planning cycles: members inside the local map are re-scored and dropped once they
fall under e_min; members outside it are remembered until the robot comes back.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware import kernels
from firmware.params import ExplorationParams


@dataclass
class Waypoint:
    x_m: float
    y_m: float
    e_bit: float
    # Made despite a ban, by a last look or for a frontier before stopping (take_up): worth
    # heading for whatever it holds, since it is that place's one try.
    taken_up: bool = False


# A change of state marks the cells of its block (this many cells a side) changed, and the
# remembered counts of every block within ray reach are forgotten.
MEMO_BLOCK_CELLS = 10


class ObservableUnknownMemo:
    """kernels.observable_unknown of window cells, remembered across planning cycles. A cell's
    count reads only the cells its rays reach, within max_range_cells of it, and where the
    window's edges are; so it holds while none of those cells changes state and the window
    stays where it is, and only counts near where the map changed are cast again."""

    def __init__(self, n_rays: int, max_range_cells: float) -> None:
        self.n_rays = n_rays
        self.max_range_cells = max_range_cells
        off = kernels.ray_offsets(n_rays, int(max_range_cells)).astype(np.int64)
        reach2 = int((off ** 2).sum(axis=2).max())
        # Block offsets at which some cell of one block is within ray reach of a cell of the other.
        b = MEMO_BLOCK_CELLS
        m = math.isqrt(reach2) // b + 2
        d = np.arange(-m, m + 1)
        gap = np.where(d != 0, (np.abs(d) - 1) * b + 1, 0)
        self._near_di, self._near_dj = np.nonzero(gap[:, None] ** 2 + gap[None, :] ** 2 <= reach2)
        self._near_di -= m
        self._near_dj -= m
        self._anchor: tuple[int, int] | None = None
        self._state = np.zeros((0, 0), np.uint8)
        self._count = np.zeros((0, 0))                # by block-padded window cell; NaN: not known

    def counts(self, local_map, state: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """observable_unknown(state, rows, cols) for window cells of local_map."""
        self._follow(state, (local_map.row0, local_map.col0))
        out = self._count[rows, cols]
        todo = np.isnan(out)
        if todo.any():
            out[todo] = kernels.observable_unknown(state, rows[todo], cols[todo], self.n_rays, self.max_range_cells)
            self._count[rows[todo], cols[todo]] = out[todo]
        return out

    def _follow(self, state: np.ndarray, anchor: tuple[int, int]) -> None:
        """Forget the counts a change of state or of the window may have changed."""
        b = MEMO_BLOCK_CELLS
        if anchor != self._anchor or state.shape != self._state.shape:
            blocks = (-(-state.shape[0] // b), -(-state.shape[1] // b))
            self._count = np.full((blocks[0] * b, blocks[1] * b), np.nan)
        else:
            changed = np.flatnonzero(state != self._state)
            if not len(changed):
                return
            n_bi, n_bj = self._count.shape[0] // b, self._count.shape[1] // b
            ci, cj = np.divmod(changed, state.shape[1])
            bi, bj = np.divmod(np.unique(ci // b * n_bj + cj // b), n_bj)
            ni = (bi[:, None] + self._near_di).ravel()
            nj = (bj[:, None] + self._near_dj).ravel()
            inside = (ni >= 0) & (ni < n_bi) & (nj >= 0) & (nj < n_bj)
            near = np.zeros((n_bi, n_bj), bool)
            near[ni[inside], nj[inside]] = True
            self._count.reshape(n_bi, b, n_bj, b).transpose(0, 2, 1, 3)[near] = np.nan
        self._anchor = anchor
        self._state = state.copy()


# Waypoints this near the window's edge are re-scored on everything mapped, not on the window.
RESCORE_MARGIN_CELLS = 2


def _rescored_in_window(local_map, w: Waypoint) -> bool:
    """Is this waypoint re-scored on the window (WaypointSet.update)?"""
    i, j = local_map.cell_of(w.x_m, w.y_m)
    n, margin = local_map.n, RESCORE_MARGIN_CELLS
    return margin <= i < n - margin and margin <= j < n - margin


# A last look (WaypointSet.look_again) tries every third cell.
LOOK_AGAIN_SPACING_CELLS = 3


class WaypointSet:
    def __init__(self, params: ExplorationParams) -> None:
        self.p = params
        self.items: list[Waypoint] = []
        self.banned: list[tuple[float, float]] = []
        # Candidate cells (global row, col) a last look took up despite a ban: each at most
        # once, so last looks end.
        self._looked_again: set[tuple[int, int]] = set()
        self._failed: list[tuple[float, float]] = []      # where the robot got no closer
        self._observable = ObservableUnknownMemo(params.info_rays, params.d_cam_m / params.resolution_m)

    def banned_mask(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        """Per point: within ban_radius of a place dropped for good?"""
        if not self.banned:
            return np.zeros(len(xs), bool)
        b = np.asarray(self.banned)
        d2 = (xs[:, None] - b[None, :, 0]) ** 2 + (ys[:, None] - b[None, :, 1]) ** 2
        return (d2 < self.p.ban_radius_m ** 2).any(axis=1)

    def is_banned(self, x_m: float, y_m: float) -> bool:
        return bool(self.banned_mask(np.array([x_m]), np.array([y_m]))[0])

    def ban(self, x_m: float, y_m: float, failed: bool = False) -> None:
        """Drop every waypoint near this point for good. failed: the robot had a route there
        but got no closer, so no last look goes near it either. (One without a route may get
        a last look: look_again offers only cells a grid path reaches now.)"""
        self.banned.append((x_m, y_m))
        if failed:
            self._failed.append((x_m, y_m))
        r2 = self.p.ban_radius_m ** 2
        self.items = [w for w in self.items if (w.x_m - x_m) ** 2 + (w.y_m - y_m) ** 2 >= r2]

    def worth_heading_for(self, x_m: float, y_m: float, held: tuple[float, float] | None = None,
                          among: list[Waypoint] | None = None) -> list[Waypoint]:
        """The members of W (or of `among`) a robot at (x_m, y_m) may head for: every one holding at least
        report_unreachable_bit, pockets (less) within pocket_reach_m, the one at held (the
        current target: a path that bends away from it does not drop it) and those taken up
        despite a ban (take_up: a frontier's one try before stopping). A pocket is
        too small to matter for the mission's end (no frontier hiding less is reported), so
        it is looked into on the way past and not driven back to across the map."""
        return [w for w in (self.items if among is None else among)
                if w.taken_up or (w.x_m, w.y_m) == held or self._worth(w.e_bit, w.x_m - x_m, w.y_m - y_m)]

    def _worth(self, e_bit, dx_m, dy_m):
        """worth_heading_for's rule, on scalars or arrays."""
        p = self.p
        return (e_bit >= p.report_unreachable_bit) | (dx_m * dx_m + dy_m * dy_m <= p.pocket_reach_m ** 2)

    def look_again(self, local_map, state: np.ndarray, reachable: np.ndarray, x_m: float,
                   y_m: float) -> Waypoint | None:
        """A robot at (x_m, y_m) about to stop: is there still information it can reach?
        Bans keep a robot from circling a place (every candidate within ban_radius_m of a
        waypoint reached or dropped), and in a small room that can hide a frontier the robot
        never looked into. So the candidate holding the most information (at least e_min, and
        worth heading for from here) is taken up despite its ban, once per candidate cell and
        never near a place the robot failed to get to; returned (and added to W), or None."""
        p = self.p
        # Finer than the candidate sub-grid: a strip the body can enter may lie between its points.
        cand, e_bit = self._scored_candidates(local_map, state, reachable, LOOK_AGAIN_SPACING_CELLS)
        keys = [(local_map.row0 + int(i), local_map.col0 + int(j)) for i, j in cand]
        xs = (local_map.col0 + cand[:, 1] + 0.5) * p.resolution_m
        ys = (local_map.row0 + cand[:, 0] + 0.5) * p.resolution_m
        ok = (e_bit >= p.min_cluster_entropy_bit) & np.array([k not in self._looked_again for k in keys], bool)
        ok &= self._worth(e_bit, xs - x_m, ys - y_m)
        if self._failed:
            f = np.asarray(self._failed)
            ok &= ~(((xs[:, None] - f[None, :, 0]) ** 2 + (ys[:, None] - f[None, :, 1]) ** 2)
                    < p.ban_radius_m ** 2).any(axis=1)
        if not ok.any():
            return None
        order = np.lexsort((cand[:, 1], cand[:, 0], -e_bit))
        k = int(order[ok[order]][0])
        self._looked_again.add(keys[k])
        return self.take_up(float(xs[k]), float(ys[k]), float(e_bit[k]))

    def take_up(self, x_m: float, y_m: float, e_bit: float) -> Waypoint:
        """Make a waypoint here despite any ban near it (the bans within ban_radius_m are
        lifted); returned, and added to W."""
        r2 = self.p.ban_radius_m ** 2
        w = Waypoint(x_m, y_m, e_bit, taken_up=True)
        self.banned = [b for b in self.banned if (b[0] - x_m) ** 2 + (b[1] - y_m) ** 2 >= r2]
        self.items.append(w)
        return w

    def failed_near(self, x_m: float, y_m: float) -> bool:
        """Is a place the robot had a route to but got no closer to within ban_radius_m?"""
        r2 = self.p.ban_radius_m ** 2
        return any((fx - x_m) ** 2 + (fy - y_m) ** 2 < r2 for fx, fy in self._failed)

    def _scored_candidates(self, local_map, state: np.ndarray, reachable: np.ndarray,
                           spacing_cells: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Reachable cells of a sub-grid (candidate_spacing_m unless spacing_cells is given)
        with enough unknown around, and the information each would observe (bits)."""
        p = self.p
        res = p.resolution_m
        max_range_cells = p.d_cam_m / res
        step = spacing_cells or max(1, int(round(p.candidate_spacing_m / res)))
        cand = np.argwhere(reachable[step // 2::step, step // 2::step]) * step + step // 2
        if len(cand):
            cells_needed = p.min_cluster_entropy_bit / p.entropy_per_cell_bit
            cand = cand[kernels.unknown_box_counts(state, int(max_range_cells), cand[:, 0], cand[:, 1]) >= cells_needed]
        if not len(cand):
            return cand.reshape(0, 2), np.zeros(0)
        counts = self._observable.counts(local_map, state, cand[:, 0].astype(np.int64), cand[:, 1].astype(np.int64))
        return cand, counts * p.entropy_per_cell_bit

    def rescore_beyond_window(self, local_map) -> int:
        """Re-score the members outside the local map on everything mapped (the window and
        the paged-out tiles, where a dense teammate's scans land too), as update() re-scores
        those inside it, and drop those under e_min; how many it dropped."""
        p = self.p
        beyond = [w for w in self.items if not _rescored_in_window(local_map, w)]
        if not beyond:
            return 0
        mapped, row0, col0 = local_map.whole_state(felt=False)
        rows = np.array([math.floor(w.y_m / p.resolution_m) for w in beyond], np.int64)
        cols = np.array([math.floor(w.x_m / p.resolution_m) for w in beyond], np.int64)
        # What lies beyond everything mapped is unknown, as far as a ray from a waypoint reaches.
        reach = int(math.ceil(p.d_cam_m / p.resolution_m)) + 1
        r_lo, c_lo = min(row0, int(rows.min()) - reach), min(col0, int(cols.min()) - reach)
        r_hi = max(row0 + mapped.shape[0], int(rows.max()) + reach + 1)
        c_hi = max(col0 + mapped.shape[1], int(cols.max()) + reach + 1)
        state = np.full((r_hi - r_lo, c_hi - c_lo), kernels.UNKNOWN, np.uint8)
        state[row0 - r_lo:row0 - r_lo + mapped.shape[0], col0 - c_lo:col0 - c_lo + mapped.shape[1]] = mapped
        counts = kernels.observable_unknown(state, rows - r_lo, cols - c_lo, p.info_rays, p.d_cam_m / p.resolution_m)
        for w, c in zip(beyond, counts):
            w.e_bit = float(c) * p.entropy_per_cell_bit
        before = len(self.items)
        self.items = [w for w in self.items if w.e_bit >= p.min_cluster_entropy_bit]
        return before - len(self.items)

    def update(self, local_map, state: np.ndarray, reachable: np.ndarray) -> None:
        """One planning cycle: re-score members inside the map, find new ones, merge."""
        p = self.p
        res = p.resolution_m
        # Re-score remembered waypoints that are back inside the local map.
        inside = [(w, *local_map.cell_of(w.x_m, w.y_m)) for w in self.items if _rescored_in_window(local_map, w)]
        if inside:
            ci = np.array([t[1] for t in inside], np.int64)
            cj = np.array([t[2] for t in inside], np.int64)
            counts = self._observable.counts(local_map, state, ci, cj)
            for (w, _, _), c in zip(inside, counts):
                w.e_bit = float(c) * p.entropy_per_cell_bit
            self.items = [w for w in self.items if w.e_bit >= p.min_cluster_entropy_bit]
        # New candidates: reachable cells on a coarse sub-grid with enough unknown around.
        cand, e_bit = self._scored_candidates(local_map, state, reachable)
        if len(cand) == 0:
            return
        xs = (local_map.col0 + cand[:, 1] + 0.5) * res
        ys = (local_map.row0 + cand[:, 0] + 0.5) * res
        r2 = p.waypoint_cluster_radius_m ** 2
        ok = (e_bit >= p.min_cluster_entropy_bit) & ~self.banned_mask(xs, ys)
        if self.items:
            w = np.array([(it.x_m, it.y_m) for it in self.items])
            ok &= ~(((xs[:, None] - w[None, :, 0]) ** 2 + (ys[:, None] - w[None, :, 1]) ** 2) < r2).any(axis=1)
        # Highest information first; ties by cell index so the choice is a pure function.
        order = np.lexsort((cand[:, 1], cand[:, 0], -e_bit))
        added: list[Waypoint] = []
        for k in order[ok[order]]:
            x, y = float(xs[k]), float(ys[k])
            if any((a.x_m - x) ** 2 + (a.y_m - y) ** 2 < r2 for a in added):
                continue
            added.append(Waypoint(x, y, float(e_bit[k])))
        self.items.extend(added)

"""Where the body fits, how much room it has, and what nearness to walls costs: the layers a
planning cycle derives from the classified map, kept from one cycle to the next and
recomputed only near the cells whose state changed.

Every output at a cell depends only on the state within DEPENDENCY cells of it: the two
distance fields are read only up to a cap (beyond it the inflation cost is zero and the
follower's room is "plenty"), and a cell's best standing point looks only at the walls
within its reach. So a cycle re-derives the cells within that reach of a change, the
distance fields on a box that reaches far enough past them for every value there to be
exact, and keeps the rest. On cells that are not FREE (never on a path) the layers hold
fixed values.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import scipy.ndimage as ndimage

from firmware import kernels
from firmware.params import ExplorationParams

# The scan fill marks the cell half a cell beyond a hit, so a wall face lies between an
# occupied cell's centre and one cell nearer the robot: a square of this half side (in
# cells) is where faces are expected; the centre alone is the most room there can be.
EXPECTED_FACE_HALF_SIDE_CELLS = 0.5
# Chamfer distances run long by at most 8.3 % (kernels.chamfer_distance); a cell's points lie
# within sqrt(2)/2 cells of its centre.
_CHAMFER_LONG = 1.0824
_HALF_DIAGONAL = math.sqrt(2.0) / 2.0
# Side of the tiles whose changes are tracked, in cells.
TILE_CELLS = 16
# Past this share of dirty tiles one pass over the known part of the window is cheaper.
_FULL_PASS_SHARE = 0.6
# Cells shifted in from outside the window: a value no state takes, so they read as changed.
_NOT_SEEN = np.uint8(255)


class Fit(NamedTuple):
    traversable: np.ndarray    # bool: FREE and the body fits somewhere in the cell
    clearance_m: np.ndarray    # float32: room from the cell's best point to the wall faces (capped)
    standing: np.ndarray       # int8: index into kernels.SUBCELL_OFFSETS of the cell's best point
    cell_cost: np.ndarray      # >= 1: the inflation cost near walls and unknown


def inflation(spare_m: np.ndarray, reach_m: float, decay_per_m: float) -> np.ndarray:
    """nav2's decaying inflation, normalised: 1 where the body touches (spare room 0 or
    less), falling as exp(-decay * spare) and reaching 0 at reach_m of spare room."""
    spare = np.clip(spare_m, 0.0, None)
    if reach_m <= 0.0:
        return np.zeros(np.shape(spare_m))
    floor = math.exp(-decay_per_m * reach_m)
    return np.clip((np.exp(-decay_per_m * spare) - floor) / (1.0 - floor), 0.0, 1.0) if floor < 1.0 else \
        np.clip(1.0 - spare / reach_m, 0.0, 1.0)


class BodyFit:
    """The Fit of a window, for one body geometry: the body plus lethal_tolerance_m, with the
    wall faces where expected or (tight) at the occupied cells' centres, the most room there
    can be."""

    def __init__(self, params: ExplorationParams, tight: bool) -> None:
        p = self.p = params
        self.tight = tight
        res = p.resolution_m
        self.body_m = p.robot_radius_m + p.lethal_tolerance_m
        self.body_cells = self.body_m / res
        h = EXPECTED_FACE_HALF_SIDE_CELLS
        self.sure_cells = _CHAMFER_LONG * (self.body_cells + h * math.sqrt(2.0)) + 1.0
        self.reach_cells = _CHAMFER_LONG * (self.body_cells + h * math.sqrt(2.0)) + 2.0
        # Distances are read up to the cap: two cells past where the inflation cost ends and
        # past where the follower counts the room as plenty (robot_radius + slow_clearance).
        self.cap_cells = float(math.ceil(max(p.inflation_radius_m, p.robot_radius_m + p.slow_clearance_m) / res
                                         + h) + 2)
        self.dependency_cells = int(math.ceil(max(self.cap_cells, self.reach_cells, self.sure_cells)))
        self._state: np.ndarray | None = None
        self._anchor = (0, 0)
        self._fit: Fit | None = None

    def update(self, state: np.ndarray, row0: int, col0: int) -> Fit:
        """The Fit of the window whose cell (0, 0) is global cell (row0, col0). The arrays
        are this object's: copy before changing them."""
        if self._state is None or self._state.shape != state.shape:
            self._fit = self._whole(state)
        else:
            changed = state != self._shifted_state(row0, col0)
            self._mark_edges_left_behind(changed, row0, col0)
            if changed.any():
                self._fit = self._shifted_fit(row0, col0)
                self._redo_near(changed, state)
        self._state = state.copy()
        self._anchor = (row0, col0)
        return self._fit

    # --- the cached window, moved with the window ---------------------------------------
    def _shift(self, old: np.ndarray, row0: int, col0: int, fill) -> np.ndarray:
        """old (anchored at self._anchor) as seen from a window anchored at (row0, col0)."""
        n_r, n_c = old.shape
        di, dj = row0 - self._anchor[0], col0 - self._anchor[1]
        out = np.full(old.shape, fill, old.dtype)
        i0, i1 = max(0, -di), min(n_r, n_r - di)
        j0, j1 = max(0, -dj), min(n_c, n_c - dj)
        if i0 < i1 and j0 < j1:
            out[i0:i1, j0:j1] = old[i0 + di:i1 + di, j0 + dj:j1 + dj]
        return out

    def _shifted_state(self, row0: int, col0: int) -> np.ndarray:
        if (row0, col0) == self._anchor:
            return self._state
        return self._shift(self._state, row0, col0, _NOT_SEEN)

    def _mark_edges_left_behind(self, changed: np.ndarray, row0: int, col0: int) -> None:
        """Cells next to a window edge that moved over known ground lost their neighbours
        beyond it: mark that edge changed, so that they are derived again."""
        di, dj = row0 - self._anchor[0], col0 - self._anchor[1]
        if di > 0:
            changed[0, :] = True
        elif di < 0:
            changed[-1, :] = True
        if dj > 0:
            changed[:, 0] = True
        elif dj < 0:
            changed[:, -1] = True

    def _shifted_fit(self, row0: int, col0: int) -> Fit:
        if (row0, col0) == self._anchor:
            return self._fit
        return Fit(*(self._shift(a, row0, col0, fill) for a, fill in zip(self._fit, (False, 0.0, 0, 1.0))))

    # --- computing ---------------------------------------------------------------------
    def _whole(self, state: np.ndarray) -> Fit:
        """The Fit from scratch, on the known cells' bounding box padded by the dependency
        reach (exact: unknown cells farther out are all alike)."""
        fit = Fit(np.zeros(state.shape, bool), np.zeros(state.shape, np.float32),
                  np.zeros(state.shape, np.int8), np.ones(state.shape, np.float64))
        known_rows = np.nonzero((state != kernels.UNKNOWN).any(axis=1))[0]
        if len(known_rows):
            known_cols = np.nonzero((state != kernels.UNKNOWN).any(axis=0))[0]
            pad = self.dependency_cells + 2
            n_r, n_c = state.shape
            self._fit_box(state, fit, (max(known_rows[0] - pad, 0), min(known_rows[-1] + pad + 1, n_r),
                                       max(known_cols[0] - pad, 0), min(known_cols[-1] + pad + 1, n_c)), None)
        return fit

    def _redo_near(self, changed: np.ndarray, state: np.ndarray) -> None:
        """Re-derive self._fit on the cells within the dependency reach of a changed cell:
        the tiles holding them grouped, each group on its bounding box widened so that every
        value inside is exact."""
        t = TILE_CELLS
        n_r, n_c = state.shape
        tr, tc = -(-n_r // t), -(-n_c // t)
        padded = np.zeros((tr * t, tc * t), bool)
        padded[:n_r, :n_c] = changed
        # Any over each tile's rows, then over its columns: reductions along contiguous memory.
        rows_any = padded.view(np.uint8).reshape(tr, t, tc * t).max(axis=1)
        tiles = rows_any.reshape(tr, tc, t).max(axis=2).view(bool)
        reach_tiles = -(-self.dependency_cells // t)
        dirty = ndimage.binary_dilation(tiles, structure=np.ones((2 * reach_tiles + 1,) * 2, bool))
        if dirty.mean() > _FULL_PASS_SHARE:
            self._fit = self._whole(state)
            return
        labels, count = ndimage.label(dirty, structure=np.ones((3, 3), bool))
        margin = self.dependency_cells + 2
        for rows, cols in ndimage.find_objects(labels):
            inner = (rows.start * t, min(rows.stop * t, n_r), cols.start * t, min(cols.stop * t, n_c))
            box = (max(inner[0] - margin, 0), min(inner[1] + margin, n_r),
                   max(inner[2] - margin, 0), min(inner[3] + margin, n_c))
            self._fit_box(state, self._fit, box, inner, changed)

    def _fit_box(self, state: np.ndarray, fit: Fit, box: tuple[int, int, int, int],
                 inner: tuple[int, int, int, int] | None, changed: np.ndarray | None = None) -> None:
        """Derive the layers on state[box] and write them to fit on inner (all of box if None);
        with `changed`, only on the cells of inner within the dependency reach of a changed
        cell (the others keep their values: nothing they depend on changed)."""
        b = (slice(box[0], box[1]), slice(box[2], box[3]))
        crop = np.ascontiguousarray(state[b])   # one kernel signature, whatever the box
        i0, i1, j0, j1 = box if inner is None else inner
        if changed is None:         # every cell of inner: as if each had changed
            near_changed, reach = np.ones(crop.shape, bool), 0
        else:                       # changes outside the box lie beyond the reach from inner
            near_changed, reach = np.ascontiguousarray(changed[b]), self.dependency_cells
        ci, cj, others = kernels.cells_near_changes(crop, near_changed, reach, i0 - box[0], i1 - box[0],
                                                    j0 - box[2], j1 - box[2])
        # Cells not FREE hold fixed values (never on a path).
        for out, value in zip(fit, (False, 0.0, 0, 1.0)):
            out[b][others] = value
        if not len(ci):
            return
        # The distance fields on the FREE cells' bounding box, widened by a box's margin.
        margin = self.dependency_cells + 2
        s0, t0 = max(ci.min() - margin, 0), max(cj.min() - margin, 0)
        sub = np.ascontiguousarray(crop[s0:min(ci.max() + 1 + margin, crop.shape[0]),
                                        t0:min(cj.max() + 1 + margin, crop.shape[1])])
        ci_sub, cj_sub = ci - s0, cj - t0
        d_occ, d_blk = kernels.chamfer_distances(sub)
        at_sub = ci_sub * sub.shape[1] + cj_sub      # flat indices: far cheaper than (i, j) pairs
        d_occ = np.minimum(np.reshape(d_occ, -1, copy=False)[at_sub], self.cap_cells)
        d_blk = np.minimum(np.reshape(d_blk, -1, copy=False)[at_sub], self.cap_cells)
        traversable, clearance_m, standing = self._body_fit(sub, ci_sub, cj_sub, d_occ)
        p = self.p
        cost = 1.0 + p.inflation_cost_weight * inflation(d_blk * p.resolution_m - self.body_m,
                                                         p.inflation_radius_m - self.body_m, p.inflation_decay_per_m)
        at = (ci + box[0]) * state.shape[1] + cj + box[2]
        for out, layer in zip(fit, (traversable, clearance_m, standing, cost)):
            np.reshape(out, -1, copy=False)[at] = layer     # a view (or an error), never a copy

    def _body_fit(self, crop: np.ndarray, ci: np.ndarray, cj: np.ndarray, d_occ_cells: np.ndarray):
        """(traversable, clearance in m, best point) of the FREE cells (ci, cj) of crop, whose
        distances to the nearest occupied cell (capped) are d_occ_cells. Cells far from
        walls fit the body at their centre; cells near them are settled by
        kernels.best_standing_points with the wall faces where expected, or (tight) with
        them at the occupied cells' centres."""
        res = self.p.resolution_m
        h = EXPECTED_FACE_HALF_SIDE_CELLS
        clearance_cells = np.maximum(d_occ_cells - h, 0.0)
        # A cell a little beyond where the centre surely fits still goes to the kernel, so that
        # a path through a door an even number of cells wide runs down its middle.
        sure = d_occ_cells >= self.sure_cells
        hopeless = d_occ_cells + _HALF_DIAGONAL < self.body_cells
        band = np.nonzero(~sure & ~hopeless)[0]
        traversable = sure.copy()
        standing = np.zeros(len(ci), np.int8)
        if len(band):
            occupied = crop == kernels.OCCUPIED
            face = 0.0 if self.tight else h
            room, best = kernels.best_standing_points(occupied, ci[band], cj[band], face, self.reach_cells)
            traversable[band] = room >= self.body_cells
            standing[band] = best
            clearance_cells[band] = room - (h - face)
        return traversable, (clearance_cells * res).astype(np.float32), standing


class PlanningFits:
    """The layers plans take, from the two geometries kept up to date side by side.

    Ordinary plans go where the body fits with the wall faces where expected and, at
    tight_passage_cost times the cost, through the tight passages: cells where it fits only
    with the faces at their cells' centres. A door the raster shows five free cells wide is
    such a passage for a body of 0.5 m: about 0.6 m between the jambs' centres, 0.5 m between
    their expected faces. Paths take one where no way of comparable cost goes round it; the
    follower slows down there (little room). The retry after a recovery takes the tight
    geometry alone, every passage at no extra cost."""

    def __init__(self, params: ExplorationParams) -> None:
        self.passage_cost = params.tight_passage_cost
        self.expected = BodyFit(params, tight=False)
        self.tight = BodyFit(params, tight=True)

    def ordinary(self, state: np.ndarray, row0: int, col0: int) -> tuple[Fit, np.ndarray]:
        """(the ordinary Fit, fresh arrays; which of its traversable cells are tight passages)."""
        expected = self.expected.update(state, row0, col0)
        fit = Fit(*(a.copy() for a in expected))
        if self.passage_cost <= 0.0:
            return fit, np.zeros(state.shape, bool)
        tight = self.tight.update(state, row0, col0)
        narrow = tight.traversable & ~expected.traversable
        fit.traversable[narrow] = True
        fit.clearance_m[narrow] = tight.clearance_m[narrow]
        fit.standing[narrow] = tight.standing[narrow]
        fit.cell_cost[narrow] = tight.cell_cost[narrow] * self.passage_cost
        return fit, narrow

    def retry(self, state: np.ndarray, row0: int, col0: int) -> Fit:
        """The tight Fit, fresh arrays."""
        return Fit(*(a.copy() for a in self.tight.update(state, row0, col0)))

"""The ground truth's regions for `pereira-oracle` (issue 23 item 6): the doorways of a map,
found by Pereira's own gate detector on the whole ground-truth map instead of on each
robot's partial, drifting view.

Pereira et al. gave their robots hand-drawn regions (the paper's "oracle", pereira.md 1.7).
Here the host finds the doorways of the ground truth once, before the mission, and hands them
to every robot as a list of doorways in the shared frame, in the wire units of a gate record
(x_dm, y_dm, dir_code, half_2cm): the file a real deployment would load from a surveyed
building plan. The firmware stays pure (it never sees the simulator's map): it folds the
doorways with its places as it folds gate records (firmware.schemes.pereira.regions), so
every robot cuts its region graph at the same doorways from the start.

The doorways are those the detector finds when everything is seen (no unknown cells, no
drift, no sensor noise), so pereira / pereira-oracle measures what finding them from the
robots' own views costs (late, missed and duplicated gates, regions that differ while
records travel), not how a person would have drawn the rooms.
"""
from __future__ import annotations

import math

import numpy as np

from firmware import kernels
from firmware.schemes.pereira.gates import detect_gates
from firmware.params import ExplorationParams
from firmware.schemes.pereira.params import with_tuning
from world_sim.occupancy_map import OccupancyMap


def truth_state(occ: OccupancyMap, res_m: float) -> tuple[np.ndarray, int, int]:
    """The ground truth as the firmware's state grid at its resolution (FREE or OCCUPIED,
    each cell what the truth holds at its centre; outside the map is wall), with one cell of
    wall around, and the global cell (row0, col0) of its corner: the robots' grid cells,
    (floor(y / res), floor(x / res)) in the shared frame."""
    c0 = math.floor(occ.origin_x_m / res_m)
    r0 = math.floor(occ.origin_y_m / res_m)
    c1 = math.ceil((occ.origin_x_m + occ.width_m) / res_m)
    r1 = math.ceil((occ.origin_y_m + occ.height_m) / res_m)
    jj, ii = np.meshgrid(np.arange(c0, c1), np.arange(r0, r1))
    col = np.floor(((jj + 0.5) * res_m - occ.origin_x_m) / occ.resolution_m).astype(np.int64)
    row = np.floor(((ii + 0.5) * res_m - occ.origin_y_m) / occ.resolution_m).astype(np.int64)
    inside = (col >= 0) & (col < occ.cols) & (row >= 0) & (row < occ.rows)
    free = np.zeros(jj.shape, bool)
    free[inside] = occ.free[row[inside], col[inside]]
    state = np.where(free, kernels.FREE, kernels.OCCUPIED).astype(np.uint8)
    return np.pad(state, 1, constant_values=kernels.OCCUPIED), r0 - 1, c0 - 1


def doorways(occ: OccupancyMap, params: ExplorationParams = ExplorationParams()) -> tuple[tuple[int, int, int, int], ...]:
    """The ground truth's doorways as (x_dm, y_dm, dir_code, half_2cm), in the detector's
    order (global cell order of their centres): what Pereira.load_region_map takes. Found at
    the robots' grid resolution with the detector's tuning of their parameters."""
    res_m = params.resolution_m
    state, row0, col0 = truth_state(occ, res_m)
    return tuple(g.wire() for g in detect_gates(state, row0, col0, res_m, with_tuning(params.pereira_widening_kappa)))

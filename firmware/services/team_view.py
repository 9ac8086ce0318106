"""What teammates' places saw: the information a waypoint still promises once everything a
LiDAR at the teammates' places would have seen counts as seen.

Schemes that share places but no maps (Bayer & Faigl's presence rule, Pereira's end-game
take-back) ask it before leaving a waypoint to the team or taking one back: a teammate that
stood near a waypoint but behind a wall, or whose view reached only part of what lies beyond
it, leaves the rest unseen.
"""
from __future__ import annotations

import numpy as np

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.services.local_map import grid_cells_of


def unseen_after_team_view_bit(sight: np.ndarray, row0: int, col0: int, waypoints_xy: np.ndarray,
                               places_xy: np.ndarray, params: ExplorationParams,
                               view_walls: np.ndarray | None = None) -> np.ndarray:
    """Per waypoint (rows of x, y in metres, all on the grid): the unknown it would show
    (observable_unknown over info_rays within d_cam_m), in bits, with the cells that
    team_view_rays cast from the teammates' places (rows of x, y) reach marked as seen. The
    grid is a sight layer (the window's, LocalMap.layers) whose cell (0, 0) is the global
    cell (row0, col0). Rays stop at walls it shows and pass through its unknown cells;
    the teammates' rays stop at view_walls too (cells of the grid's shape, if given; a
    place's own cell never blocks)."""
    p = params
    wxy = np.asarray(waypoints_xy, np.float64).reshape(-1, 2)
    if not len(wxy):
        return np.zeros(0)
    w_ij, _inside = grid_cells_of(wxy, row0, col0, sight.shape, p.resolution_m)
    # Contiguous, as the kernels were compiled for at warm-up (a column view would compile anew).
    wi, wj = np.ascontiguousarray(w_ij[:, 0]), np.ascontiguousarray(w_ij[:, 1])
    reach_cells = p.d_cam_m / p.resolution_m
    # observable_unknown below reads only the unknown cells its rays from these waypoints
    # reach: what the teammates saw elsewhere does not change the result.
    counted = np.zeros(sight.shape, bool)
    kernels.mark_visible(sight, wi, wj, p.info_rays, reach_cells, sight == kernels.UNKNOWN, counted)
    # A place more than 2 d_cam from every waypoint sees nothing the waypoint would (1 m
    # spare for cell rounding), so it is left out: the same result, much less ray casting.
    pxy = np.asarray(places_xy, np.float64).reshape(-1, 2)
    if len(pxy):
        d2 = ((pxy[:, None, :] - wxy[None, :, :]) ** 2).sum(axis=2).min(axis=1)
        pxy = pxy[d2 <= (2.0 * p.d_cam_m + 1.0) ** 2]
    ij, inside = grid_cells_of(pxy, row0, col0, sight.shape, p.resolution_m)
    pi, pj = np.ascontiguousarray(ij[inside, 0]), np.ascontiguousarray(ij[inside, 1])
    place_sight = sight
    if view_walls is not None:
        place_sight = sight.copy()
        place_sight[view_walls] = kernels.OCCUPIED
        place_sight[pi, pj] = sight[pi, pj]
    seen = np.zeros(sight.shape, bool)
    kernels.mark_visible(place_sight, pi, pj, p.team_view_rays, reach_cells, counted, seen)
    team_sight = sight.copy()
    team_sight[seen] = kernels.SEEN_BY_TEAM
    return kernels.observable_unknown(team_sight, wi, wj, p.info_rays, reach_cells) * p.entropy_per_cell_bit


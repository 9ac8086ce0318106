"""Compile the firmware's numba kernels before a robot's tick loop starts.

The kernels compile on their first call (or load from numba's cache), which on a fresh
install takes seconds: inside the first lidar and planning tasks that would be a start-up
stall of the robot's real-time loop. warm_up runs one scan fold and one planning cycle's
map work on a small synthetic room, open on one side, and a small topological map, with the
same types the firmware uses.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.ndimage as ndimage

from firmware import kernels
from firmware.services.motion import scan_points, travel_share_seen
from firmware.params import ExplorationParams
from firmware.services.grid_paths import GridPaths
from firmware.services.known_map import KnownMap, find_frontiers
from firmware.services.local_map import LocalMap
from firmware.services.scan_match import ScanMatcher
from firmware.services.topo_map import TopoMap
from firmware.services.waypoints import WaypointSet

_ROOM_RADIUS_M = 3.0
_BEAMS = 360


def warm_up(params: ExplorationParams) -> None:
    """Run every kernel of a lidar and a planning task once (on a small window)."""
    small = dataclasses.replace(params, d_local_m=min(params.d_local_m, 2 * _ROOM_RADIUS_M + 2.0),
                                recenter_distance_m=min(params.recenter_distance_m, 1.0))
    local_map = LocalMap(small, 0.0, 0.0)
    ranges_m = np.full(_BEAMS, _ROOM_RADIUS_M, np.float32)
    ranges_m[:_BEAMS // 6] = 0.0        # a sector without returns: unknown, so there are waypoints
    local_map.integrate_scan(0.0, 0.0, 0.0, -np.pi, 2 * np.pi / _BEAMS, ranges_m, 10.0)
    for tight in (False, True):
        layers = local_map.layers(tight=tight)
        i, j = local_map.cell_of(0.0, 0.0)
        paths = GridPaths(layers.traversable, layers.cell_cost, i, j)
        paths.settle_first(np.array([i]), np.array([j + 5]))
        paths.settle_below(10.0)
        paths.path(i, j + 10)
        WaypointSet(small).update(local_map, layers.sight, paths.reachable)
        find_frontiers(layers.sight, paths.reachable, small)
    # Everything mapped, as a robot about to stop (or without a route) plans on it.
    known = KnownMap(small, local_map)
    known.refresh(0.0, 0.0, 0)
    known.route(1.0, 0.0)
    known.frontiers()
    # A scan matched to the map (when scan_match is on).
    ScanMatcher(small).match(local_map, 0.0, 0.0, 0.0, -np.pi, 2 * np.pi / _BEAMS, ranges_m, 10.0)
    # The slip check: a scan laid over the one before it.
    points = scan_points(-np.pi, 2 * np.pi / _BEAMS, ranges_m, 10.0)
    travel_share_seen(points, points, 0.05, 0.0, 0.0, 0.0)
    # A teammate's view, as Bayer & Faigl's presence rule casts it.
    ij, inside = local_map.cells_of(np.array([[1.0, 0.0]]))
    kernels.mark_visible(layers.sight, ij[inside, 0], ij[inside, 1], small.team_view_rays,
                         small.d_cam_m / small.resolution_m, layers.sight == kernels.UNKNOWN,
                         np.zeros(layers.sight.shape, bool))
    # The walls' Voronoi cells, as Pereira et al.'s gate finder looks for doorways.
    walls = layers.state == kernels.OCCUPIED
    _d, (wall_i, wall_j) = ndimage.distance_transform_edt(~walls, return_indices=True)
    cell_i, cell_j = np.indices(walls.shape)
    kernels.wall_jump_cells(~walls, wall_i, wall_j, (wall_i - cell_i) ** 2 + (wall_j - cell_j) ** 2, -0.5)
    # The boundary of the observed area, as Meier et al.'s polygon maps trace it.
    kernels.crack_contours(layers.state == kernels.FREE, layers.state == kernels.OCCUPIED)
    # The topological map: a record folded, one more merged in, graph costs on the result.
    topo = TopoMap(small.d_build_m, small.d_connect_m)
    topo.add((0, 0, 0, 0, 1, 0, 0))
    topo.positions()
    topo.add((0, round(small.d_build_m * 100), 0, 0, 1, 0, 0))
    topo.costs_from(0.0, 0.0)

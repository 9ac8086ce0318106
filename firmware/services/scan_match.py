"""Where the robot is, from its LiDAR and its own map: scan-to-map matching.

Wheel odometry drifts, and its heading error bends everything mapped after it: a few
degrees after a few hundred metres put a door mapped at the start a metre from where the
robot, back there, sees it, and the old map paged back in then shows walls across the way
(one robot on Willow Garage, seed 0: 13168 s with the drift the simulated odometry has,
7730 s without it). A real robot localises against its map; with scan_match on, so does this one. Every
match_every_m of travel (or match_every_rad of turning) a scan is matched to the window
before it is folded in: poses on a small grid around the one odometry predicts are scored
by how close the scan's endpoints fall to the walls mapped (a correlative matcher, Olson
2009), and the best becomes the pose, the correction carried on for the odometry that
follows (services.pose). Where the scan fits as well without a correction (along a
corridor with no feature, all poses score alike), odometry is trusted: of the poses that
fit within scan_match_min_gain of the best the one nearest the prediction is taken. It
runs only with ExplorationParams.scan_match (off by default).
"""
from __future__ import annotations

import math

import numpy as np

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.services.local_map import LocalMap

# The likelihood a wall is at a point: a Gaussian of the distance to the nearest occupied
# cell, this wide (cells). A hit lands within half a cell of its wall; odometry between two
# matches moves it far less than a cell.
FIELD_SIGMA_CELLS = 1.0
# A scan is matched only if this many of its endpoints fall near walls already mapped (field
# above one half at the predicted pose): too few, and there is nothing to match against.
MIN_ANCHORED_ENDPOINTS = 30


class ScanMatcher:
    def __init__(self, params: ExplorationParams) -> None:
        p = self.p = params
        n_t = max(1, int(round(p.scan_match_search_m / p.scan_match_step_m)))
        n_r = max(1, int(round(p.scan_match_search_rad / p.scan_match_step_rad)))
        self._dxy = np.arange(-n_t, n_t + 1) * p.scan_match_step_m
        self._dyaw = np.arange(-n_r, n_r + 1) * p.scan_match_step_rad
        # How far each candidate correction is from none, in search steps: the tie-break.
        k, a, b = np.meshgrid(np.arange(-n_r, n_r + 1), np.arange(-n_t, n_t + 1), np.arange(-n_t, n_t + 1),
                              indexing="ij")
        self._offset2 = (k * k + a * a + b * b).astype(np.float64)
        self._last: tuple[float, float, float] | None = None
        self.matches = 0           # scans matched
        self.corrections = 0       # ... of which moved the pose

    def due(self, x_m: float, y_m: float, yaw_rad: float) -> bool:
        """Has the robot moved or turned enough since the last match for another?"""
        if not self.p.scan_match:
            return False
        last = self._last
        if last is None:
            return True
        turned = abs((yaw_rad - last[2] + math.pi) % (2 * math.pi) - math.pi)
        return math.hypot(x_m - last[0], y_m - last[1]) >= self.p.scan_match_every_m \
            or turned >= self.p.scan_match_every_rad

    def match(self, local_map: LocalMap, x_m: float, y_m: float, yaw_rad: float, angle_min_rad: float,
              angle_increment_rad: float, ranges_m: np.ndarray, range_max_m: float) -> tuple[float, float, float] | None:
        """The pose (x, y, yaw) at which the scan (robot frame) best fits the window, or
        None if too little of it falls on walls mapped to tell."""
        self._last = (x_m, y_m, yaw_rad)
        r = np.asarray(ranges_m, np.float64)
        angles = angle_min_rad + np.arange(len(r)) * angle_increment_rad
        hit = (r > 0.0) & (r < range_max_m)
        # The fill marks the cell half a cell beyond each hit (kernels.polar_fill): compare the
        # scan's points there, or every match would pull the robot half a cell off the walls.
        beyond = r[hit] + 0.5 * self.p.resolution_m
        bx, by = beyond * np.cos(angles[hit]), beyond * np.sin(angles[hit])
        if len(bx) < MIN_ANCHORED_ENDPOINTS:
            return None
        field, row0, col0 = self._field(local_map, x_m, y_m, float(np.max(r[hit])))
        if field is None:
            return None
        res = self.p.resolution_m
        zero = np.zeros(1)
        anchored = kernels.scan_match_scores(
            (field > 0.5).astype(np.float64), row0, col0, res, x_m, y_m, yaw_rad, bx, by, zero, zero, zero)
        if anchored[0, 0, 0] * len(bx) < MIN_ANCHORED_ENDPOINTS:
            return None
        scores = kernels.scan_match_scores(field, row0, col0, res, x_m, y_m, yaw_rad, bx, by,
                                           self._dxy, self._dxy, self._dyaw)
        self.matches += 1
        good = scores >= scores.max() - self.p.scan_match_min_gain
        if good.flat[self._offset2.size // 2]:      # no correction fits as well as any
            return x_m, y_m, yaw_rad
        k, a, b = np.unravel_index(int(np.argmin(np.where(good, self._offset2, np.inf))), scores.shape)
        self.corrections += 1
        yaw = (yaw_rad + self._dyaw[k] + math.pi) % (2 * math.pi) - math.pi
        return x_m + float(self._dxy[a]), y_m + float(self._dxy[b]), yaw

    def _field(self, local_map: LocalMap, x_m: float, y_m: float, reach_m: float):
        """The wall likelihood on the window cells within reach_m (and the search) of the
        robot, and that crop's global (row0, col0); (None, 0, 0) if no wall is mapped there."""
        res = self.p.resolution_m
        half = int(math.ceil((reach_m + self.p.scan_match_search_m) / res)) + 2
        i, j = local_map.cell_of(x_m, y_m)
        n = local_map.n
        i0, i1, j0, j1 = max(i - half, 0), min(i + half + 1, n), max(j - half, 0), min(j + half + 1, n)
        if i0 >= i1 or j0 >= j1:
            return None, 0, 0
        state = local_map.state_of(i0, i1, j0, j1)
        occupied = state == kernels.OCCUPIED
        if not occupied.any():
            return None, 0, 0
        d = kernels.chamfer_distance(occupied).astype(np.float64)
        field = np.exp(-0.5 * (d / FIELD_SIGMA_CELLS) ** 2)
        return field, local_map.row0 + i0, local_map.col0 + j0

"""The robot's dense local map: a log-odds window of fixed size that follows the robot.

Memory is fixed by the window size, whatever the area explored. What leaves the window is
forgotten here; `KeyframeStore` keeps one binned scan per topological vertex, so a place
that comes back into the window is restored from the scans taken there, instead of looking
unexplored again.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from firmware import kernels
from firmware.params import ExplorationParams


class BinnedScan(NamedTuple):
    """A 360-degree scan in the world frame: bin b covers the bearings within half a bin of
    bearing0_rad + b * 2 pi / len(ranges_m); a range of 0 means no beam fell in the bin."""

    x_m: float
    y_m: float
    bearing0_rad: float
    ranges_m: np.ndarray
    range_max_m: float


class KeyframeStore:
    """One binned scan per place, kept in the scan's own bearings (see `bin_scan`).

    Ranges are stored in centimetres as uint16: 720 bytes per place at 360 bins."""

    def __init__(self, bins: int) -> None:
        self.bins = bins
        self._xy_m = np.zeros((64, 2), np.float64)
        self._bearing0_rad = np.zeros(64, np.float64)
        self._ranges_cm = np.zeros((64, bins), np.uint16)
        self._range_max_m = np.zeros(64, np.float64)
        self.count = 0

    def add(self, scan: BinnedScan) -> None:
        if self.count == len(self._xy_m):
            grow = len(self._xy_m)
            self._xy_m = np.concatenate([self._xy_m, np.zeros((grow, 2))])
            self._bearing0_rad = np.concatenate([self._bearing0_rad, np.zeros(grow)])
            self._ranges_cm = np.concatenate([self._ranges_cm, np.zeros((grow, self.bins), np.uint16)])
            self._range_max_m = np.concatenate([self._range_max_m, np.zeros(grow)])
        k = self.count
        self._xy_m[k] = (scan.x_m, scan.y_m)
        self._bearing0_rad[k] = scan.bearing0_rad
        self._ranges_cm[k] = np.clip(np.round(scan.ranges_m * 100.0), 0, 65535).astype(np.uint16)
        self._range_max_m[k] = scan.range_max_m
        self.count += 1

    def has_within(self, x_m: float, y_m: float, radius_m: float) -> bool:
        xy = self._xy_m[: self.count]
        return bool((((xy[:, 0] - x_m) ** 2 + (xy[:, 1] - y_m) ** 2) < radius_m * radius_m).any())

    def near(self, x_lo: float, x_hi: float, y_lo: float, y_hi: float) -> np.ndarray:
        """Indices of keyframes whose range disc may touch the rectangle."""
        xy = self._xy_m[: self.count]
        reach = self._range_max_m[: self.count]
        dx = np.maximum(np.maximum(x_lo - xy[:, 0], xy[:, 0] - x_hi), 0.0)
        dy = np.maximum(np.maximum(y_lo - xy[:, 1], xy[:, 1] - y_hi), 0.0)
        return np.nonzero(dx * dx + dy * dy <= reach * reach)[0]

    def get(self, k: int) -> BinnedScan:
        return BinnedScan(
            float(self._xy_m[k, 0]),
            float(self._xy_m[k, 1]),
            float(self._bearing0_rad[k]),
            self._ranges_cm[k].astype(np.float64) / 100.0,
            float(self._range_max_m[k]),
        )


def bin_scan(x_m: float, y_m: float, yaw_rad: float, angle_min_rad: float, angle_increment_rad: float,
             ranges_m: np.ndarray, range_max_m: float, bins: int) -> BinnedScan:
    """A robot-frame scan in `bins` world-frame bins (shortest beam per bin), the first bin
    centred on the first beam. The bins follow the beams rather than fixed world bearings:
    with as many bins as beams each beam keeps its own bearing, so a place restored from a
    keyframe is the scan that was taken there. Bins on fixed bearings moved every beam by
    up to half a bin; along a wall seen at a grazing angle that shifts the range enough to
    clear cells behind the wall, and places restored that way grew frontiers in ground
    explored long before (a robot alone on maze_a, seed 0, drove 6 km)."""
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


# A keyframe on the mesh link: sender u8, x_cm i32, y_cm i32, bearing of the first bin u16
# (in 1/65536 of a turn), range_max_cm u16, bins u16, then one u16 range in cm per bin
# (little-endian): 15 + 2 * bins bytes.
_KEYFRAME_HEAD = struct.Struct("<BiiHHH")
_TURN_UNITS = 65536


def keyframe_bytes(bins: int) -> int:
    return _KEYFRAME_HEAD.size + 2 * bins


def encode_keyframe(sender_id: int, scan: BinnedScan) -> bytes:
    ranges_cm = np.clip(np.round(scan.ranges_m * 100.0), 0, 65535).astype("<u2")
    bearing0 = round(scan.bearing0_rad % (2 * math.pi) / (2 * math.pi) * _TURN_UNITS) % _TURN_UNITS
    return _KEYFRAME_HEAD.pack(sender_id, round(scan.x_m * 100), round(scan.y_m * 100), bearing0,
                               min(65535, round(scan.range_max_m * 100)), len(ranges_cm)) + ranges_cm.tobytes()


def decode_keyframe(data: bytes) -> tuple[int, BinnedScan] | None:
    """(sender, scan), or None if malformed."""
    if len(data) < _KEYFRAME_HEAD.size:
        return None
    sender, x_cm, y_cm, bearing0, range_max_cm, bins = _KEYFRAME_HEAD.unpack_from(data)
    if bins == 0 or len(data) != keyframe_bytes(bins) or range_max_cm == 0:
        return None
    ranges = np.frombuffer(data, "<u2", bins, _KEYFRAME_HEAD.size).astype(np.float64) / 100.0
    return sender, BinnedScan(x_cm / 100.0, y_cm / 100.0, bearing0 * (2 * math.pi / _TURN_UNITS),
                              ranges, range_max_cm / 100.0)


@dataclass
class MapLayers:
    """What planning needs, derived from the log-odds once per planning cycle."""

    state: np.ndarray          # UNKNOWN / FREE / OCCUPIED per cell
    sight: np.ndarray          # state with unknown cells next to walls closed, for ray casting
    traversable: np.ndarray    # bool: known free and radius + margin away from obstacles
    cell_cost: np.ndarray      # >= 1, grows near walls and unknown space


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


class LocalMap:
    MAX_BUMP_CELLS = 7 * 64
    def __init__(self, params: ExplorationParams, x_m: float, y_m: float, keyframes: KeyframeStore) -> None:
        self.p = params
        self.n = params.window_cells
        self.logodds = np.zeros((self.n, self.n), np.float32)
        self.keyframes = keyframes
        self.row0, self.col0 = self._anchor_for(x_m, y_m)
        self.bumps: list[tuple[float, float]] = []   # obstacles felt, not seen (mark_obstacle_ahead)

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

    def contains(self, x_m: float, y_m: float, margin_cells: int = 0) -> bool:
        i, j = self.cell_of(x_m, y_m)
        return margin_cells <= i < self.n - margin_cells and margin_cells <= j < self.n - margin_cells

    def bounds_m(self) -> tuple[float, float, float, float]:
        res = self.p.resolution_m
        return (self.col0 * res, (self.col0 + self.n) * res, self.row0 * res, (self.row0 + self.n) * res)

    # --- updates ------------------------------------------------------------------
    def integrate_keyframe(self, scan: BinnedScan) -> None:
        """Fold a peer's keyframe (dense-map sharing) into the whole window."""
        self._fill_binned(scan, (0, self.n, 0, self.n))

    def mark_obstacle_ahead(self, x_m: float, y_m: float, yaw_rad: float, distance_m: float) -> None:
        """Remember an obstacle just ahead of the robot (a short arc across its heading) that
        the LiDAR does not show. Kept apart from the log-odds, so later scans that see free
        space there cannot erase it and send the robot into the same spot again."""
        for off in np.linspace(-0.6, 0.6, 7):
            self.bumps.append((x_m + distance_m * math.cos(yaw_rad + off), y_m + distance_m * math.sin(yaw_rad + off)))
        del self.bumps[:-self.MAX_BUMP_CELLS]  # bounded memory: the oldest are forgotten first

    def _fill(self, px, py, bin0, binw, ranges, range_max, region) -> None:
        p = self.p
        kernels.polar_fill(self.logodds, self.row0, self.col0, p.resolution_m, px, py, bin0, binw,
                           ranges, range_max, p.logodds_hit, p.logodds_miss, p.logodds_min,
                           p.logodds_max, *region)

    def _fill_binned(self, scan: BinnedScan, region) -> None:
        self._fill(scan.x_m, scan.y_m, scan.bearing0_rad, 2 * math.pi / len(scan.ranges_m),
                   np.ascontiguousarray(scan.ranges_m, np.float64), scan.range_max_m, region)

    def integrate_scan(self, x_m, y_m, yaw_rad, angle_min_rad, angle_increment_rad, ranges_m, range_max_m) -> None:
        ranges = np.ascontiguousarray(ranges_m, dtype=np.float64)
        self._fill(x_m, y_m, yaw_rad + angle_min_rad, angle_increment_rad, ranges, range_max_m,
                   (0, self.n, 0, self.n))

    def follow(self, x_m: float, y_m: float) -> bool:
        """Re-anchor the window on the robot once it has drifted off centre; restore the
        newly exposed cells from keyframes. Returns True if the window moved."""
        cx, cy = self.center_of(self.n // 2, self.n // 2)
        if max(abs(x_m - cx), abs(y_m - cy)) < self.p.recenter_distance_m:
            return False
        row0, col0 = self._anchor_for(x_m, y_m)
        di, dj = row0 - self.row0, col0 - self.col0
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
            self._restore(region)
        return True

    def _restore(self, region: tuple[int, int, int, int]) -> None:
        r_lo, r_hi, c_lo, c_hi = region
        res = self.p.resolution_m
        x_lo, y_lo = (self.col0 + c_lo) * res, (self.row0 + r_lo) * res
        x_hi, y_hi = (self.col0 + c_hi) * res, (self.row0 + r_hi) * res
        for k in self.keyframes.near(x_lo, x_hi, y_lo, y_hi):
            self._fill_binned(self.keyframes.get(int(k)), region)

    # --- derived layers -------------------------------------------------------------
    def layers(self) -> MapLayers:
        p = self.p
        state = kernels.classify(self.logodds, p.logodds_occupied, p.logodds_free)
        for bx, by in self.bumps:
            i, j = self.cell_of(bx, by)
            if 0 <= i < self.n and 0 <= j < self.n:
                state[i, j] = kernels.OCCUPIED
        traversable = np.zeros(state.shape, bool)
        cell_cost = np.ones(state.shape, np.float64)
        # Only known cells can be traversable, and distances matter only up to the clearance
        # cost's reach: work on the known cells' bounding box, padded by that reach (exact,
        # since unknown cells outside it count as blocked anyway).
        known_rows = np.nonzero((state != kernels.UNKNOWN).any(axis=1))[0]
        if len(known_rows):
            known_cols = np.nonzero((state != kernels.UNKNOWN).any(axis=0))[0]
            pad = int(np.ceil(max(p.clearance_cost_m, p.robot_radius_m + p.safety_margin_m) / p.resolution_m)) + 1
            i0, i1 = max(known_rows[0] - pad, 0), min(known_rows[-1] + pad + 1, self.n)
            j0, j1 = max(known_cols[0] - pad, 0), min(known_cols[-1] + pad + 1, self.n)
            crop = state[i0:i1, j0:j1]
            d_occ_cells, d_block_cells = kernels.chamfer_distances(crop)
            keep_out_cells = (p.robot_radius_m + p.safety_margin_m) / p.resolution_m
            traversable[i0:i1, j0:j1] = (crop == kernels.FREE) & (d_occ_cells >= keep_out_cells)
            near = np.clip((p.clearance_cost_m - d_block_cells * p.resolution_m) / p.clearance_cost_m, 0.0, 1.0)
            cell_cost[i0:i1, j0:j1] = 1.0 + p.clearance_cost_weight * near
        return MapLayers(state=state, sight=close_wall_gaps(state), traversable=traversable, cell_cost=cell_cost)

"""The hgrid: this robot's record of where the team has been (../shared/schemes/wiserx.md
sections 1.4, 1.8, A6-A9, A18, A19, A22, A27 and 5.8).

It holds points: this robot's own positions and its estimates of its teammates' positions,
each with its robot, its weight omega = min(1, 1 / Tr Sigma) frozen when it was recorded,
and its time; and per robot a liveness flag tau, shared by all of that robot's points, so a
failed robot's whole history stops counting by one flip (eq. 7), and counts again when it is
heard again. Points live in this robot's odometry frame (where its map, frontiers and
estimates are); the cells live in the boundary's frame, known at deployment, and this robot
knows its own start in it (the rigid transform `to_boundary`).

Cells: a uniform grid over the boundary box, n = ceil(L / r) per side (side L / n <= r).
Only footprint cells count: those holding at least footprint_min_area_m2 of navigable area
(a coarse floor plan handed over at deployment, A8), or every cell when no plan is given.
A cell is filled (A7):

- `disc`: at least fill_disc_share of its test points (a lattice of fill_lattice_m) lie
  within r of a recorded position of a live robot, own positions included;
- `pts2` (the authors' code): at least 2 recorded positions of live robots lie in it.

fill = filled footprint cells / footprint cells. Pure and deterministic.
"""
from __future__ import annotations

import math

import numpy as np

from firmware.schemes.wiserx.params import WiserxParams
from firmware.services.deployment import rigid_transform


class HGrid:
    def __init__(self, own_id: int, boundary_m: tuple[float, float, float, float],
                 to_boundary: tuple[float, float, float] = (0.0, 0.0, 0.0), params: WiserxParams = WiserxParams(),
                 navigable_m2: np.ndarray | None = None, plan_cell_m: float = 1.0) -> None:
        """boundary_m: (x0, y0, x1, y1) in the boundary's frame; to_boundary: (x, y, yaw)
        of this robot's odometry origin in that frame; navigable_m2: navigable area (m^2)
        per square of plan_cell_m, row 0 at y0 and column 0 at x0 (None: every cell counts)."""
        x0, y0, x1, y1 = (float(v) for v in boundary_m)
        if not (x1 > x0 and y1 > y0):
            raise ValueError(f"an hgrid needs a boundary with x1 > x0 and y1 > y0, got {boundary_m}")
        self.own_id = own_id
        self.p = params
        self.x0, self.y0 = x0, y0
        r = params.sensor_range_m
        self.nx = max(1, math.ceil((x1 - x0) / r - 1e-9))
        self.ny = max(1, math.ceil((y1 - y0) / r - 1e-9))
        self.sx = (x1 - x0) / self.nx
        self.sy = (y1 - y0) / self.ny
        self._to_boundary = to_boundary
        self.footprint = self._footprint(navigable_m2, plan_cell_m)
        # The disc rule's test points: kx by ky per cell.
        self.kx = max(1, math.ceil(self.sx / params.fill_lattice_m - 1e-9))
        self.ky = max(1, math.ceil(self.sy / params.fill_lattice_m - 1e-9))
        self._lx = x0 + (np.arange(self.nx * self.kx) + 0.5) * (self.sx / self.kx)
        self._ly = y0 + (np.arange(self.ny * self.ky) + 0.5) * (self.sy / self.ky)
        self._marks: dict[int, np.ndarray] = {}      # robot -> test points within r of its positions
        self._counts: dict[int, np.ndarray] = {}     # robot -> its positions per cell
        self._heard: dict[int, np.ndarray] = {}      # robot -> cells it said it filled (row-major)
        self.tau: dict[int, bool] = {own_id: True}
        self._x: list[float] = []
        self._y: list[float] = []
        self._robot: list[int] = []
        self._omega: list[float] = []
        self._stamp: list[int] = []
        self._arrays: tuple | None = None

    # --- geometry ---------------------------------------------------------------------
    def to_boundary(self, x_m, y_m):
        """Points of this robot's odometry frame in the boundary's frame."""
        return rigid_transform(self._to_boundary, x_m, y_m)

    def cell_of(self, bx: float, by: float) -> tuple[int, int] | None:
        """(row, col) of the cell holding a point of the boundary's frame (a point on the
        boundary's far edge belongs to the last cell), None outside the boundary."""
        fx = (bx - self.x0) / self.sx
        fy = (by - self.y0) / self.sy
        if not (0.0 <= fx <= self.nx and 0.0 <= fy <= self.ny):
            return None
        return min(int(fy), self.ny - 1), min(int(fx), self.nx - 1)

    def inside(self, x_m: float, y_m: float, margin_m: float = 0.0) -> bool:
        """Is a point of the odometry frame within margin_m of the boundary box?"""
        bx, by = self.to_boundary(x_m, y_m)
        return bool(-margin_m <= bx - self.x0 <= self.nx * self.sx + margin_m
                    and -margin_m <= by - self.y0 <= self.ny * self.sy + margin_m)

    def _footprint(self, navigable_m2: np.ndarray | None, plan_cell_m: float) -> np.ndarray:
        if navigable_m2 is None:
            return np.ones((self.ny, self.nx), bool)
        area = np.asarray(navigable_m2, dtype=np.float64)
        rows, cols = np.nonzero(area > 0.0)
        cx = self.x0 + (cols + 0.5) * plan_cell_m
        cy = self.y0 + (rows + 0.5) * plan_cell_m
        ci = np.clip(((cy - self.y0) / self.sy).astype(np.int64), 0, self.ny - 1)
        cj = np.clip(((cx - self.x0) / self.sx).astype(np.int64), 0, self.nx - 1)
        total = np.zeros((self.ny, self.nx))
        np.add.at(total, (ci, cj), area[rows, cols])
        return total >= self.p.footprint_min_area_m2

    # --- recording --------------------------------------------------------------------
    def insert(self, robot: int, x_m: float, y_m: float, omega: float, stamp_us: int) -> None:
        """A position of `robot` (this robot's odometry frame) with its weight."""
        self._x.append(float(x_m))
        self._y.append(float(y_m))
        self._robot.append(int(robot))
        self._omega.append(float(omega))
        self._stamp.append(int(stamp_us))
        self._arrays = None
        self.tau.setdefault(robot, True)
        bx, by = (float(v) for v in self.to_boundary(x_m, y_m))
        cell = self.cell_of(bx, by)
        if cell is not None:
            counts = self._counts.setdefault(robot, np.zeros((self.ny, self.nx), np.int32))
            counts[cell] += 1
        self._mark(robot, bx, by)

    def _mark(self, robot: int, bx: float, by: float) -> None:
        r = self.p.sensor_range_m
        jx = np.nonzero(np.abs(self._lx - bx) <= r)[0]
        iy = np.nonzero(np.abs(self._ly - by) <= r)[0]
        if not len(jx) or not len(iy):
            return
        marks = self._marks.setdefault(robot, np.zeros((len(self._ly), len(self._lx)), bool))
        near = (self._lx[jx][None, :] - bx) ** 2 + (self._ly[iy][:, None] - by) ** 2 <= r * r
        marks[iy[0]:iy[-1] + 1, jx[0]:jx[-1] + 1] |= near

    def set_alive(self, robot: int, alive: bool) -> None:
        """tau of a robot (its points all count, or none does); this robot is always alive."""
        if robot != self.own_id:
            self.tau[robot] = bool(alive)

    def _counting(self, robot: int) -> bool:
        return robot == self.own_id or not self.p.tau_enabled or self.tau.get(robot, True)

    # --- reading ------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self._x)

    def hear(self, robot: int, cells: list[int]) -> None:
        """A teammate's word (wiserx-lora's digest) that it filled these cells (row-major
        numbers) by its own positions: they count as filled while it is alive."""
        heard = self._heard.setdefault(robot, np.zeros(self.ny * self.nx, bool))
        heard[[c for c in cells if 0 <= c < len(heard)]] = True
        self.tau.setdefault(robot, True)

    def filled(self) -> np.ndarray:
        """Per cell (ny, nx): filled under the fill rule by live robots' positions, or heard
        filled from a live robot."""
        out = self._filled_by([k for k in self._marks if self._counting(k)] if self.p.fill_rule == "disc" else
                              [k for k in self._counts if self._counting(k)])
        for k, heard in self._heard.items():
            if self._counting(k):
                out |= heard.reshape(self.ny, self.nx)
        return out

    def own_filled(self) -> np.ndarray:
        """Per cell (ny, nx): filled under the fill rule by this robot's own positions."""
        return self._filled_by([self.own_id] if self.own_id in (self._marks if self.p.fill_rule == "disc"
                                                                else self._counts) else [])

    def _filled_by(self, robots: list[int]) -> np.ndarray:
        if not robots:
            return np.zeros((self.ny, self.nx), bool)
        if self.p.fill_rule == "pts2":
            return sum(self._counts[k] for k in robots) >= 2
        marked = np.logical_or.reduce([self._marks[k] for k in robots])
        share = marked.reshape(self.ny, self.ky, self.nx, self.kx).mean(axis=(1, 3))
        return share >= self.p.fill_disc_share - 1e-12

    def fill(self) -> float:
        """Filled footprint cells over footprint cells (0 with no footprint cell)."""
        n = int(self.footprint.sum())
        return float((self.filled() & self.footprint).sum()) / n if n else 0.0

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(x_m, y_m, robot, omega, stamp_us) of every point, in insertion order."""
        if self._arrays is None:
            self._arrays = (np.array(self._x), np.array(self._y), np.array(self._robot, np.int64),
                            np.array(self._omega), np.array(self._stamp, np.int64))
        return self._arrays

    def teammate_points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x_m, y_m, omega) of the points that count as loss (eq. 7): teammates' points
        (never this robot's own, A22) of robots alive (tau = 1; all with tau_enabled off)."""
        x, y, robot, omega, _ = self.arrays()
        keep = robot != self.own_id
        if self.p.tau_enabled and keep.any():
            dead = [k for k, alive in self.tau.items() if not alive]
            if dead:
                keep &= ~np.isin(robot, dead)
        return x[keep], y[keep], omega[keep]

    def counts_by_robot(self) -> dict[int, int]:
        _, _, robot, _, _ = self.arrays()
        ids, n = np.unique(robot, return_counts=True)
        return {int(k): int(c) for k, c in zip(ids, n)}

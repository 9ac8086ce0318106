"""Ground-truth occupancy map shared by every part of the simulated world."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """A 2-D ground truth: True where a robot may be, False for wall (and for anything the
    source map did not mark free). Row 0 is the lowest y, column 0 the lowest x; cell
    (row, col) covers [origin + col*res, origin + (col+1)*res) in x and likewise in y."""

    free: np.ndarray = field(repr=False)  # bool, shape (rows, cols)
    resolution_m: float
    origin_x_m: float
    origin_y_m: float
    name: str = "map"

    @property
    def rows(self) -> int:
        return int(self.free.shape[0])

    @property
    def cols(self) -> int:
        return int(self.free.shape[1])

    @property
    def width_m(self) -> float:
        return self.cols * self.resolution_m

    @property
    def height_m(self) -> float:
        return self.rows * self.resolution_m

    def wall_u8(self) -> np.ndarray:
        """1 for wall, 0 for free: the layout the numba kernels take."""
        return (~self.free).astype(np.uint8)

    def cell_of(self, x_m: float, y_m: float) -> tuple[int, int]:
        """(row, col) of the cell containing the point; may lie outside the map."""
        col = int(np.floor((x_m - self.origin_x_m) / self.resolution_m))
        row = int(np.floor((y_m - self.origin_y_m) / self.resolution_m))
        return row, col

    def center_of(self, row: int, col: int) -> tuple[float, float]:
        return (
            self.origin_x_m + (col + 0.5) * self.resolution_m,
            self.origin_y_m + (row + 0.5) * self.resolution_m,
        )

    def is_free_point(self, x_m: float, y_m: float) -> bool:
        row, col = self.cell_of(x_m, y_m)
        return 0 <= row < self.rows and 0 <= col < self.cols and bool(self.free[row, col])

"""Link budget of the simulated 868 MHz channel: log-distance path loss, a loss per wall
crossed on the straight line between two nodes, optional log-normal shadowing, thermal noise
floor and the receiver sensitivity per spreading factor and bandwidth.

Wall crossings are counted with an exact grid traversal. Positions are first quantised to
`SUBCELLS_PER_CELL` steps per map cell, so the traversal is pure integer arithmetic: the
numba kernel and the plain-Python reference visit exactly the same cells, including lines
that run along grid lines or through cell corners (no floating-point tie breaking).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numba
import numpy as np

from hal.lora import LoraModulation
from world_sim.occupancy_map import OccupancyMap

# Quantisation of positions before the traversal: 1/1024 of a cell (0.05 mm on a 5 cm map)
# is far below anything the robots resolve, and keeps every product in the integer
# traversal below 2**63 for maps up to ~10^5 cells on a side.
SUBCELLS_PER_CELL = 1024

# Receiver sensitivity in dBm by (spreading factor, bandwidth in Hz): the measured table of
# LoRaSim (Bor et al. 2016, loraDir.py `sf7..sf12` arrays, columns BW125/BW250/BW500).
# These are measurements of one SX1272 setup, not the datasheet: they are not monotonic in
# SF (SF12 reads 1.25 dB worse than SF11 at BW125), and we keep them as measured.
# SF6 (implicit header only) is not in the table; the RN2483 does not offer it either.
SENSITIVITY_DBM: dict[tuple[int, int], float] = {
    (7, 125_000): -126.5, (7, 250_000): -124.25, (7, 500_000): -120.75,
    (8, 125_000): -127.25, (8, 250_000): -126.75, (8, 500_000): -124.0,
    (9, 125_000): -131.25, (9, 250_000): -128.25, (9, 500_000): -127.5,
    (10, 125_000): -132.75, (10, 250_000): -130.25, (10, 500_000): -128.75,
    (11, 125_000): -134.5, (11, 250_000): -132.75, (11, 500_000): -128.75,
    (12, 125_000): -133.25, (12, 250_000): -132.25, (12, 500_000): -132.25,
}


# FSK at the RN2483's default 50 kb/s: the SX1276 datasheet gives about -108 dBm at
# 38.4 kb/s (FDA 20 kHz); a faster rate needs a few dB more.
FSK_SENSITIVITY_DBM = -105.0


def sensitivity_dbm(mod: LoraModulation) -> float:
    try:
        return SENSITIVITY_DBM[(mod.sf, mod.bw_hz)]
    except KeyError:
        raise ValueError(
            f"no receiver sensitivity for SF{mod.sf} at {mod.bw_hz} Hz "
            f"(table covers SF7..SF12 at 125/250/500 kHz)"
        ) from None


@dataclass(frozen=True)
class PropagationParams:
    path_loss_exponent: float = 2.7
    reference_loss_db: float = 31.2        # free-space loss at reference_distance_m, 868 MHz
    reference_distance_m: float = 1.0
    wall_loss_db: float = 6.0              # per wall crossed (run of wall cells on the line)
    shadowing_std_db: float = 0.0          # log-normal shadowing, drawn per frame and receiver
    noise_figure_db: float = 6.0

    def __post_init__(self) -> None:
        checks = (
            ("path_loss_exponent", self.path_loss_exponent > 0),
            ("reference_distance_m", self.reference_distance_m > 0),
            ("wall_loss_db", self.wall_loss_db >= 0),
            ("shadowing_std_db", self.shadowing_std_db >= 0),
        )
        for name, ok in checks:
            if not ok or not math.isfinite(getattr(self, name)):
                raise ValueError(f"PropagationParams.{name} out of range: {getattr(self, name)!r}")

    def path_loss_db(self, distance_m: float, walls: int = 0) -> float:
        """Log-distance loss; closer than the reference distance counts as the reference
        distance (the far-field formula is meaningless inside it)."""
        d_m = max(distance_m, self.reference_distance_m)
        return (
            self.reference_loss_db
            + 10.0 * self.path_loss_exponent * math.log10(d_m / self.reference_distance_m)
            + walls * self.wall_loss_db
        )

    def noise_floor_dbm(self, bw_hz: int) -> float:
        """Thermal noise in the channel bandwidth plus the receiver noise figure."""
        return -174.0 + 10.0 * math.log10(bw_hz) + self.noise_figure_db

    def max_range_m(self, tx_power_dbm: float, mod: LoraModulation, walls: int = 0) -> float:
        """Largest distance at which a frame through `walls` walls is still at or above the
        receiver sensitivity (no shadowing). 0 if even the reference distance is too far."""
        budget_db = tx_power_dbm - sensitivity_dbm(mod) - self.reference_loss_db - walls * self.wall_loss_db
        if budget_db < 0:
            return 0.0
        return self.reference_distance_m * 10.0 ** (budget_db / (10.0 * self.path_loss_exponent))


# ---------------------------------------------------------------------------------------------
# Wall crossings: exact traversal of the cells a segment passes through.
#
# The segment runs from (x0, y0) to (x1, y1) in integer sub-cell units; a point (x, y) lies in
# cell (row, col) = (y // Q, x // Q) (floor, so a point on a grid line belongs to the cell above
# / right of it). The traversal visits, in order, every cell containing some point of the
# segment. Moving in +x the segment enters the next column AT the parameter t where it meets
# the grid line; moving in -x it leaves the current column just AFTER that t. So at equal t a
# positive-direction crossing happens before a negative-direction one, and crossings of the
# same kind at the same t happen together (a diagonal step through a corner).
# A "wall crossed" is a free -> wall transition along the visited cells. Cells outside the map
# count as free (nothing is known to block there).
# ---------------------------------------------------------------------------------------------


def _floordiv(a: int, b: int) -> int:
    return a // b


def traversed_cells_ref(x0: int, y0: int, x1: int, y1: int, q: int = SUBCELLS_PER_CELL) -> list[tuple[int, int]]:
    """Plain-Python reference: the (row, col) cells the segment visits, in order, computed by
    sorting every grid-line crossing event with exact rational parameters."""
    col, row = _floordiv(x0, q), _floordiv(y0, q)
    col_end, row_end = _floordiv(x1, q), _floordiv(y1, q)
    events: list[tuple[Fraction, int, int, int]] = []  # (t, kind, axis, step); kind 0 = at t, 1 = after t
    dx, dy = x1 - x0, y1 - y0
    if col_end > col:
        events += [(Fraction(k * q - x0, dx), 0, 0, +1) for k in range(col + 1, col_end + 1)]
    elif col_end < col:
        events += [(Fraction(x0 - k * q, -dx), 1, 0, -1) for k in range(col, col_end, -1)]
    if row_end > row:
        events += [(Fraction(k * q - y0, dy), 0, 1, +1) for k in range(row + 1, row_end + 1)]
    elif row_end < row:
        events += [(Fraction(y0 - k * q, -dy), 1, 1, -1) for k in range(row, row_end, -1)]
    events.sort()
    cells = [(row, col)]
    i = 0
    while i < len(events):
        t, kind = events[i][0], events[i][1]
        while i < len(events) and events[i][0] == t and events[i][1] == kind:
            if events[i][2] == 0:
                col += events[i][3]
            else:
                row += events[i][3]
            i += 1
        cells.append((row, col))
    return cells


def _is_wall(wall: np.ndarray, row: int, col: int) -> bool:
    return 0 <= row < wall.shape[0] and 0 <= col < wall.shape[1] and bool(wall[row, col])


def count_wall_crossings_ref(wall: np.ndarray, x0: int, y0: int, x1: int, y1: int,
                             q: int = SUBCELLS_PER_CELL) -> int:
    """Reference count of free -> wall transitions along the traversal (wall: uint8, 1 = wall)."""
    crossings = 0
    previous = None
    for row, col in traversed_cells_ref(x0, y0, x1, y1, q):
        here = _is_wall(wall, row, col)
        if previous is not None and here and not previous:
            crossings += 1
        previous = here
    return crossings


@numba.njit(cache=True, nogil=True)
def _wall_at(wall, row, col):
    if row < 0 or col < 0 or row >= wall.shape[0] or col >= wall.shape[1]:
        return False
    return wall[row, col] != 0


@numba.njit(cache=True, nogil=True)
def count_wall_crossings_nb(wall, x0, y0, x1, y1, q):
    """Numba kernel: the same traversal as `traversed_cells_ref`, merged on the fly.
    Comparing t_x = nx / |dx| with t_y = ny / |dy| by cross-multiplication keeps it exact."""
    col = x0 // q
    row = y0 // q
    col_end = x1 // q
    row_end = y1 // q
    adx = abs(x1 - x0)
    ady = abs(y1 - y0)
    sx = 1 if col_end > col else -1
    sy = 1 if row_end > row else -1
    steps_x = abs(col_end - col)
    steps_y = abs(row_end - row)
    # kind 0: entering at t (positive direction), kind 1: leaving just after t (negative)
    kind_x = 0 if sx > 0 else 1
    kind_y = 0 if sy > 0 else 1
    previous = _wall_at(wall, row, col)
    crossings = 0
    while steps_x > 0 or steps_y > 0:
        move_x = steps_x > 0
        move_y = steps_y > 0
        if move_x and move_y:
            # distance (in sub-cells) from the start to the next grid line on each axis
            if sx > 0:
                nx = (col + 1) * q - x0
            else:
                nx = x0 - col * q
            if sy > 0:
                ny = (row + 1) * q - y0
            else:
                ny = y0 - row * q
            lhs = nx * ady   # t_x * |dx| * |dy|
            rhs = ny * adx   # t_y * |dx| * |dy|
            if lhs < rhs or (lhs == rhs and kind_x < kind_y):
                move_y = False
            elif rhs < lhs or (lhs == rhs and kind_y < kind_x):
                move_x = False
        if move_x:
            col += sx
            steps_x -= 1
        if move_y:
            row += sy
            steps_y -= 1
        here = _wall_at(wall, row, col)
        if here and not previous:
            crossings += 1
        previous = here
    return crossings


def quantise(occupancy: OccupancyMap, x_m: float, y_m: float) -> tuple[int, int]:
    """A position in integer sub-cell units of the map grid."""
    scale = SUBCELLS_PER_CELL / occupancy.resolution_m
    return (
        int(math.floor((x_m - occupancy.origin_x_m) * scale + 0.5)),
        int(math.floor((y_m - occupancy.origin_y_m) * scale + 0.5)),
    )


class WallCounter:
    """Counts walls between two points of one map; keeps the uint8 wall grid the kernel reads."""

    def __init__(self, occupancy: OccupancyMap) -> None:
        self.occupancy = occupancy
        self.wall_u8 = np.ascontiguousarray(occupancy.wall_u8())

    def walls_between(self, a_xy_m: tuple[float, float], b_xy_m: tuple[float, float]) -> int:
        x0, y0 = quantise(self.occupancy, *a_xy_m)
        x1, y1 = quantise(self.occupancy, *b_xy_m)
        return int(count_wall_crossings_nb(self.wall_u8, x0, y0, x1, y1, SUBCELLS_PER_CELL))

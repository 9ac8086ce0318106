"""How much of a map a robot can see at all: the coverage ceiling of a map for a planner
that keeps its robot a given clearance from walls.

Coverage (DESIGN.md) is scored against the area the robot *body* can reach. A planner keeps
more room than the body needs (its safety margin), so rooms behind doors narrower than
twice its clearance can only be looked into from outside, and whatever the LiDAR cannot see
through the door stays unseen however well the team explores. This module measures that
part: it stands a simulated LiDAR on every cell centre the planner could drive to (on a
stride) and marks what it sees, with the same ray kernel that scores missions."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy import ndimage

from firmware.params import ExplorationParams
from world_sim.occupancy_map import OccupancyMap
from world_sim.raycast import cast_and_mark
from world_sim.ros_map import reachable_free


_PLANNER = ExplorationParams()
# How far the firmware keeps a robot's centre from walls: its radius plus the lethal tolerance.
PLANNER_CLEARANCE_M = round(_PLANNER.robot_radius_m + _PLANNER.lethal_tolerance_m, 6)


@dataclass(frozen=True)
class ObservableShare:
    clearance_m: float
    stride_m: float
    reachable_m2: float        # free area the robot body can sweep from the start (the coverage metric's)
    drivable_m2: float         # cells whose centre keeps clearance_m from every wall cell's, connected to the start
    stations: int              # drivable cells the LiDAR was stood on
    observable_share: float    # share of the reachable area the LiDAR sees from some station: the coverage ceiling
    unobservable_m2: float     # reachable area it sees from none

    def to_json(self) -> dict:
        return {"clearance_m": self.clearance_m, "stride_m": self.stride_m,
                "reachable_m2": round(self.reachable_m2, 3), "drivable_m2": round(self.drivable_m2, 3),
                "stations": self.stations, "observable_share": round(self.observable_share, 6),
                "unobservable_m2": round(self.unobservable_m2, 3)}


def drivable_centres(occ: OccupancyMap, start_xy: tuple[float, float], clearance_m: float) -> np.ndarray:
    """Bool grid of the cells whose centre lies at least clearance_m from the centre of every
    wall cell (the firmware's traversability rule, on the ground truth; beyond the map's edge
    counts as wall), in the connected (8-neighbour) component nearest the start. Raises
    ValueError when no cell keeps it."""
    walled = np.pad(occ.free, 1, constant_values=False)
    clearance = ndimage.distance_transform_edt(walled)[1:-1, 1:-1] * occ.resolution_m
    labels, count = ndimage.label(clearance >= clearance_m, structure=np.ones((3, 3), dtype=bool))
    if count == 0:
        raise ValueError(f"map '{occ.name}': no cell keeps {clearance_m} m from every wall")
    row, col = occ.cell_of(float(start_xy[0]), float(start_xy[1]))
    rows, cols = np.nonzero(labels)
    nearest = int(np.argmin((rows - row) ** 2 + (cols - col) ** 2))
    return labels == labels[rows[nearest], cols[nearest]]


def observable_share(occ: OccupancyMap, start_xy: tuple[float, float], clearance_m: float, *,
                     body_radius_m: float, lidar_beams: int, lidar_range_m: float, stride_m: float,
                     on_station: Callable[[int], None] = lambda n: None) -> tuple[ObservableShare, np.ndarray]:
    """The coverage ceiling and the bool grid of reachable cells no station sees.
    Stations are the drivable cells on a grid of stride_m (rounded to whole cells, at least
    one); on_station(k) is called every 1000 stations for a progress bar."""
    if not clearance_m > 0 or not stride_m > 0 or lidar_beams < 1 or not lidar_range_m > 0:
        raise ValueError(f"clearance_m, stride_m, lidar_beams and lidar_range_m must be positive, got "
                         f"{clearance_m}, {stride_m}, {lidar_beams}, {lidar_range_m}")
    reachable = reachable_free(occ, start_xy, connectivity=4, robot_radius_m=body_radius_m)
    drivable = drivable_centres(occ, start_xy, clearance_m)
    step = max(1, int(round(stride_m / occ.resolution_m)))
    on_grid = np.zeros_like(drivable)
    on_grid[::step, ::step] = True
    rows, cols = np.nonzero(drivable & on_grid)
    seen = np.zeros(occ.free.shape, dtype=np.bool_)
    wall = occ.wall_u8()
    angles = np.linspace(-np.pi, np.pi, lidar_beams, endpoint=False)
    for k, (r, c) in enumerate(zip(rows, cols)):
        x, y = occ.center_of(int(r), int(c))
        cast_and_mark(seen, wall, occ.origin_x_m, occ.origin_y_m, occ.resolution_m, x, y, angles, lidar_range_m)
        if (k + 1) % 1000 == 0:
            on_station(1000)
    on_station(len(rows) % 1000)
    unseen = reachable & ~seen
    cell_m2 = occ.resolution_m ** 2
    share = float((reachable & seen).sum() / reachable.sum())
    return ObservableShare(clearance_m=clearance_m, stride_m=step * occ.resolution_m,
                           reachable_m2=float(reachable.sum() * cell_m2), drivable_m2=float(drivable.sum() * cell_m2),
                           stations=int(len(rows)), observable_share=share,
                           unobservable_m2=float(unseen.sum() * cell_m2)), unseen

"""What a team knows about where it explores before it starts, as some schemes assume
(WiSER-X: "dimensions of the outer boundary known", ../shared/schemes/wiserx.md section 1.1
and A8): the boundary box, a coarse plan of where there is navigable area in it, this
robot's start in it and the team's size. Nothing of the map itself.

Frames: the boundary has a frame of its own (the deployment's). `origin` is where this
robot's odometry frame lies in it: the identity for a team sharing the deployment's frame,
the robot's start pose for one whose odometry starts at its own origin.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Deployment:
    boundary_m: tuple[float, float, float, float]        # x0, y0, x1, y1 in the deployment's frame
    origin: tuple[float, float, float]                   # this robot's odometry origin there: x_m, y_m, yaw_rad
    team_size: int
    # Navigable area (m^2) per square of plan_cell_m, row 0 at y0 and column 0 at x0; None
    # when no plan was given.
    navigable_m2: np.ndarray | None = field(default=None, repr=False)
    plan_cell_m: float = 1.0

    def __post_init__(self) -> None:
        x0, y0, x1, y1 = self.boundary_m
        if not all(math.isfinite(v) for v in (*self.boundary_m, *self.origin)) or not (x1 > x0 and y1 > y0):
            raise ValueError(f"a deployment needs a finite boundary with x1 > x0 and y1 > y0 and a finite origin, "
                             f"got {self.boundary_m} and {self.origin}")
        if self.team_size < 1:
            raise ValueError(f"a deployment's team_size must be at least 1, got {self.team_size}")
        if not self.plan_cell_m > 0:
            raise ValueError(f"a deployment's plan_cell_m must be positive, got {self.plan_cell_m}")

    def to_deployment(self, x_m, y_m):
        """Points of this robot's odometry frame in the deployment's frame."""
        return rigid_transform(self.origin, x_m, y_m)


def rigid_transform(pose: tuple[float, float, float], x_m, y_m):
    """Points (scalars or arrays) of a frame whose origin lies at pose = (x_m, y_m, yaw_rad)
    in another, in that other frame."""
    tx, ty, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    return c * x - s * y + float(tx), s * x + c * y + float(ty)

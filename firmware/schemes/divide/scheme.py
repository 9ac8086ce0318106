"""Divide and conquer as a Scheme. Robot i takes region i of the deployment's floor plan (the
one WiSER-X's coverage record counts over). Every planning cycle (and before the planner's
last looks) it keeps, of its own waypoints:

- those in its region or within REGION_MARGIN_M of it, if there are any;
- else, while the robot is not in its region yet, all of them, each costed the more the
  farther from the region it lies (Candidate.penalty_m), so it explores its way there (a
  frontier nearer the region as the crow flies need not lead there);
- else none: its region holds nothing more it can see, and it stops.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from firmware.schemes.base import Candidate, OwnPlaces, PlanningView, Scheme, Services, cost_along_graph
from firmware.schemes.divide.partition import Partition
from hal.samples import OdometrySample

# A plan cell counts towards a region with at least this navigable area (a sliver of floor
# at a plan cell's corner does not pull a centre into a wall).
MIN_CELL_AREA_M2 = 0.25
# A waypoint stands back from the unknown it looks at: one this close to the region looks
# into it.
REGION_MARGIN_M = 3.0
# The robot is in its region within this of one of the region's plan cells' centres (half a
# 1 m plan cell's diagonal is 0.71 m).
IN_REGION_M = 1.0


class Divide(Scheme):
    name = "divide"
    doc = "divide and conquer: the floor plan split into one region per robot, each explores its own, nothing sent"
    variants = {"": "each robot explores only its region of the deployment's floor plan (k-means of its cells)"}
    needs = frozenset({"floor_plan"})

    def attach(self, services: Services) -> None:
        super().attach(services)
        d = services.deployment
        self._places = OwnPlaces(services)
        x0, y0, _, _ = d.boundary_m
        self.partition = Partition(d.navigable_m2, d.plan_cell_m, x0, y0, MIN_CELL_AREA_M2, d.team_size)
        self.region = services.robot_id % d.team_size
        self._cells = cKDTree(self.partition.cells_of(self.region))
        self._to_region: dict[tuple[float, float], float] = {}   # transit waypoints -> their distance to the region
        self._dropped = 0

    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        self._places.on_travel(pose)

    def distance_to_region_m(self, x_m, y_m) -> np.ndarray:
        """How far points of this robot's odometry frame lie from its region's plan cells."""
        bx, by = self.s.deployment.to_deployment(x_m, y_m)
        if self._cells.n == 0:
            return np.full(np.shape(bx), np.inf)
        return self._cells.query(np.column_stack([np.ravel(bx), np.ravel(by)]))[0]

    def filter_waypoints(self, view: PlanningView) -> None:
        wp = self.s.waypoints
        self._to_region = {}
        if not wp.items:
            return
        to_region = self.distance_to_region_m([w.x_m for w in wp.items], [w.y_m for w in wp.items])
        keep = to_region <= REGION_MARGIN_M
        if not keep.any() and self.distance_to_region_m(view.x_m, view.y_m)[0] > IN_REGION_M:
            keep[:] = True
            self._to_region = {(w.x_m, w.y_m): float(d) for w, d in zip(wp.items, to_region)}
        self._dropped += int((~keep).sum())
        wp.items = [w for w, k in zip(wp.items, keep) if k]

    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        cost_along_graph(view, own)
        for c in own:
            c.penalty_m = self._to_region.get((c.x_m, c.y_m), 0.0)
        return own

    def stats(self) -> dict[str, int]:
        return {"divide_waypoints_outside": self._dropped}

    def drawables(self) -> dict:
        d = self.s.deployment
        cells = self.partition.cells_of(self.region)
        # In this robot's odometry frame (the inverse of to_deployment).
        ox, oy, yaw = d.origin
        c, s = np.cos(yaw), np.sin(yaw)
        dx, dy = cells[:, 0] - ox, cells[:, 1] - oy
        return {"title": "each robot's region (plan cells)", "what": "cells of its region",
                "points": np.column_stack([c * dx + s * dy, -s * dx + c * dy])}

"""The no-communication baseline: every robot explores alone, as if it had no teammates.

It keeps a topological graph of its own places (a vertex every d_build of travel) to route
to its remembered waypoints beyond the local window, and sends nothing."""
from __future__ import annotations

import numpy as np

from firmware.schemes.base import Candidate, OwnPlaces, PlanningView, Scheme, Services, cost_along_graph
from hal.samples import OdometrySample


class Independent(Scheme):
    name = "independent"
    doc = "no communication at all"
    variants = {"": "no communication at all"}

    def attach(self, services: Services) -> None:
        super().attach(services)
        self._places = OwnPlaces(services)

    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        self._places.on_travel(pose)

    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        cost_along_graph(view, own)
        return own

    def drawables(self) -> dict:
        topo = self.s.topo
        xy = topo.positions()
        return {"title": "each robot's own places (never shared)", "points": xy, "what": "places",
                "segments": xy[topo.edges] if len(topo.edges) else np.zeros((0, 2, 2))}

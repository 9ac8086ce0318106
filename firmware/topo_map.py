"""Bayer & Faigl's topological map (IV-B): vertices at visited positions, each with the set
of robots seen there and the information still obtainable from it, edges between vertices
closer than d_connect, and long-distance costs by Dijkstra over the graph.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import networkx as nx
import numpy as np


@dataclass
class Vertex:
    x_m: float
    y_m: float
    z_m: float
    ids: set[int] = field(default_factory=set)   # robots that reported presence here
    e_inf_bit: float = 0.0                       # information obtainable here (eq. 4)


class TopoMap:
    def __init__(self, d_build_m: float, d_connect_m: float) -> None:
        self.d_build_m = d_build_m
        self.d_connect_m = d_connect_m
        self.vertices: list[Vertex] = []
        self.graph = nx.Graph()
        self._xy = np.zeros((0, 2), np.float64)

    def __len__(self) -> int:
        return len(self.vertices)

    def positions(self) -> np.ndarray:
        return self._xy

    def nearest(self, x_m: float, y_m: float) -> int | None:
        if not self.vertices:
            return None
        d2 = (self._xy[:, 0] - x_m) ** 2 + (self._xy[:, 1] - y_m) ** 2
        return int(np.argmin(d2))  # argmin takes the lowest index on ties: deterministic

    def apply(self, sender_id: int, x_m: float, y_m: float, z_m: float, presence: bool, e_inf_bit: float) -> int:
        """Algorithm 1: merge a record into the closest vertex within d_build, else add a
        vertex and connect it to every vertex within d_connect. Returns the vertex index."""
        h = self.nearest(x_m, y_m)
        if h is not None and math.hypot(self._xy[h, 0] - x_m, self._xy[h, 1] - y_m) < self.d_build_m:
            v = self.vertices[h]
            if presence:
                v.ids.add(sender_id)
            v.e_inf_bit = e_inf_bit
            return h
        v = Vertex(x_m, y_m, z_m, {sender_id} if presence else set(), e_inf_bit)
        k = len(self.vertices)
        self.vertices.append(v)
        d = np.hypot(self._xy[:, 0] - x_m, self._xy[:, 1] - y_m) if k else np.zeros(0)
        self._xy = np.vstack([self._xy, [[x_m, y_m]]])
        self.graph.add_node(k)
        for other in np.nonzero(d <= self.d_connect_m)[0]:
            self.graph.add_edge(k, int(other), weight=float(d[other]))
        return k

    def costs_from(self, x_m: float, y_m: float) -> tuple[int | None, dict[int, float]]:
        """Graph distance from the vertex nearest to (x, y) to every vertex it reaches."""
        src = self.nearest(x_m, y_m)
        if src is None:
            return None, {}
        return src, nx.single_source_dijkstra_path_length(self.graph, src, weight="weight")

    def cost_to(self, costs: dict[int, float], x_m: float, y_m: float) -> tuple[float, int | None]:
        """Cost from the robot to a point beyond its local map: graph distance to the reached
        vertex closest to the point plus the straight line from there; when the graph is
        disconnected this falls back to the closest vertex the robot can reach."""
        if not costs:
            return math.inf, None
        idx = np.fromiter(costs.keys(), np.int64, len(costs))
        g = np.fromiter(costs.values(), np.float64, len(costs))
        e = np.hypot(self._xy[idx, 0] - x_m, self._xy[idx, 1] - y_m)
        k = int(np.argmin(e + 1e-9 * idx))  # closest reached vertex; lowest index on ties
        return float(g[k] + e[k]), int(idx[k])

    def path(self, src: int, dst: int) -> list[int]:
        return nx.dijkstra_path(self.graph, src, dst, weight="weight")

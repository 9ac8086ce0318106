"""The boundary B of the observed area as closed contours on cell borders (meier.md A2, A3,
5.1 step 2): the region is the FREE cells, 4-connected (the rest 8-connected); every crack
between a FREE cell and one that is not is a step of a contour, directed so that the FREE
cell lies on its left: outer boundaries run counter-clockwise, holes clockwise. Each crack
is typed by the cell across it: OCCUPIED -> a wall, anything else (unknown, outside the
grid) -> a frontier.

Corners are lattice points (x = column, y = row, cell (row, col) spans [col, col + 1] x
[row, row + 1]). Where two FREE cells touch only at a corner (a pinch), a contour turns
left, so the two stay apart as 4-connectivity says. Contours start at their lowest (y, x)
corner and are numbered in that order.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from firmware import kernels

FRONTIER_EDGE = 0
WALL_EDGE = 1

# Directions of a step along a crack: +x, +y, -x, -y (counter-clockwise order, so a left
# turn is the next one).
_STEPS = ((1, 0), (0, 1), (-1, 0), (0, -1))


class Contour(NamedTuple):
    corners: np.ndarray      # int64 (n, 2): lattice (x, y) of each corner, in order
    edge_types: np.ndarray   # int8 (n,): type of the crack from corner k to corner k + 1


def trace_contours(state: np.ndarray) -> list[Contour]:
    """The contours of the FREE cells of a classified grid (kernels.UNKNOWN / FREE /
    OCCUPIED), in order of their lowest (y, x) corner."""
    free = state == kernels.FREE
    rows, cols = free.shape
    padded = np.zeros((rows + 2, cols + 2), bool)
    padded[1:-1, 1:-1] = free
    occupied = np.zeros((rows + 2, cols + 2), bool)
    occupied[1:-1, 1:-1] = state == kernels.OCCUPIED
    # Outgoing cracks per start corner: direction index -> (edge type).
    out: dict[tuple[int, int], dict[int, int]] = {}

    def add(x: int, y: int, d: int, across_r: int, across_c: int) -> None:
        out.setdefault((x, y), {})[d] = WALL_EDGE if occupied[across_r + 1, across_c + 1] else FRONTIER_EDGE

    for r, c in zip(*np.nonzero(free)):
        r, c = int(r), int(c)
        if not padded[r, c + 1]:          # below is not free: step +x along y = r
            add(c, r, 0, r - 1, c)
        if not padded[r + 1, c + 2]:      # right: step +y along x = c + 1
            add(c + 1, r, 1, r, c + 1)
        if not padded[r + 2, c + 1]:      # above: step -x along y = r + 1
            add(c + 1, r + 1, 2, r + 1, c)
        if not padded[r + 1, c]:          # left: step -y along x = c
            add(c, r + 1, 3, r, c - 1)
    contours = []
    for start in sorted(out, key=lambda p: (p[1], p[0])):
        while out.get(start):
            contours.append(_follow(out, start))
    return contours


def _follow(out: dict[tuple[int, int], dict[int, int]], start: tuple[int, int]) -> Contour:
    """Walk one contour from start, taking each crack once, left turns first."""
    corners, types = [], []
    here = start
    first = d = min(out[start])
    while True:
        t = out[here].pop(d)
        if not out[here]:
            del out[here]
        corners.append(here)
        types.append(t)
        here = (here[0] + _STEPS[d][0], here[1] + _STEPS[d][1])
        options = out.get(here, {})
        # Left turn, straight on, right turn: the first that exists. Back at the start, the
        # crack it began with counts among them (taken already: the contour closes there).
        d = next(k for k in ((d + 1) % 4, d, (d + 3) % 4) if k in options or (here == start and k == first))
        if here == start and d == first:
            break
    return Contour(np.array(corners, np.int64).reshape(-1, 2), np.array(types, np.int8))


def signed_area(corners: np.ndarray) -> float:
    """Shoelace area of a closed ring of (x, y): positive counter-clockwise."""
    x, y = corners[:, 0].astype(np.float64), corners[:, 1].astype(np.float64)
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))

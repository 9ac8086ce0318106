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


class Contour(NamedTuple):
    corners: np.ndarray      # int64 (n, 2): lattice (x, y) of each corner, in order
    edge_types: np.ndarray   # int8 (n,): type of the crack from corner k to corner k + 1


def trace_contours(state: np.ndarray) -> list[Contour]:
    """The contours of the FREE cells of a classified grid (kernels.UNKNOWN / FREE /
    OCCUPIED), in order of their lowest (y, x) corner (kernels.crack_contours)."""
    corners, types, starts = kernels.crack_contours(state == kernels.FREE, state == kernels.OCCUPIED)
    return [Contour(corners[a:b], types[a:b]) for a, b in zip(starts[:-1].tolist(), starts[1:].tolist())]


def rotated(a: np.ndarray, k: int) -> np.ndarray:
    """A closed sequence started at its element k (-len(a) <= k <= len(a)): np.roll(a, -k)
    along the first axis, without np.roll's cost on the short rings traced by the thousand."""
    return np.concatenate((a[k:], a[:k]))


def signed_area(corners: np.ndarray) -> float:
    """Shoelace area of a closed ring of (x, y): positive counter-clockwise."""
    x, y = corners[:, 0].astype(np.float64), corners[:, 1].astype(np.float64)
    return 0.5 * float(np.dot(x, rotated(y, 1)) - np.dot(rotated(x, 1), y))


def smooth_edge_types(types: np.ndarray, min_run: int) -> np.ndarray:
    """A closed contour's crack types with every run shorter than min_run cracks taking the
    type around it: first frontier gaps in walls (a gap of a crack or two is no way on and
    mostly a beam that missed), then specks of wall in frontiers. A contour of one type, or
    min_run 1, is returned as it is."""
    out = np.asarray(types).copy()
    if min_run <= 1:
        return out
    for short in (FRONTIER_EDGE, WALL_EDGE):
        change = np.nonzero(out != rotated(out, -1))[0]
        if len(change) == 0:
            return out
        lengths = np.diff(np.append(change, change[0] + len(out)))
        flip = np.repeat((lengths < min_run) & (out[change] == short), lengths)   # from change[0] on
        out[((change[0] + np.arange(len(out))) % len(out))[flip]] = 1 - short
    return out


def hold_junctions(types: np.ndarray, kept: np.ndarray, max_cracks: int) -> np.ndarray:
    """A closed contour's crack types with each wall/frontier junction moved back onto a
    kept vertex (a corner index in `kept`) at most max_cracks wall cracks away, the wall
    cracks between becoming frontier. Vertices never move, so a junction that advances along
    a wall as the frontier does would leave a vertex behind at every update; held, it leaves
    one every max_cracks. Only walls ever turn into frontier: a frontier is never drawn as a
    wall. A junction on a kept vertex, or with none that near, stays where it is."""
    types = np.asarray(types)
    out = types.copy()
    n = len(types)
    if max_cracks <= 0 or n == 0 or len(kept) == 0:
        return out
    is_kept = np.zeros(n, bool)
    is_kept[np.asarray(kept, np.int64)] = True
    for k in np.nonzero(types != rotated(types, -1))[0].tolist():
        if is_kept[k]:
            continue
        into_frontier = types[k] == FRONTIER_EDGE      # wall cracks before corner k, else after it
        for d in range(1, max_cracks + 1):
            crack = (k - d) % n if into_frontier else (k + d - 1) % n
            if types[crack] != WALL_EDGE:
                break
            if is_kept[(k - d) % n if into_frontier else (k + d) % n]:
                held = (k - np.arange(1, d + 1)) % n if into_frontier else (k + np.arange(d)) % n
                out[held] = FRONTIER_EDGE
                break
    return out

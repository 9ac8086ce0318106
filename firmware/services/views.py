"""What sensors at given places would see in the local map, remembered between planning
cycles: casting hundreds of rays from every teammate place, every cycle, was a tenth of a
team mission's time, and most of those places lie where the map no longer changes.

A view from a place depends only on the sight layer within the rays' reach of it, so it is
kept (in world cells) and used again as long as no cell in that square has changed since
it was cast (services.local_map.SightChanges) and the square lies inside the window. The
union of the views is the one kernels.mark_visible casts from all the places at once."""
from __future__ import annotations

import numpy as np

from firmware import kernels
from firmware.services.local_map import LocalMap


class ViewCache:
    def __init__(self, n_rays: int, reach_cells: float) -> None:
        self.n_rays = n_rays
        self.reach_cells = reach_cells
        self._margin = int(reach_cells) + 2          # ray offsets round to at most one cell more
        # world cell of a place -> (epoch cast at, world rows, world cols of what it sees)
        self._views: dict[tuple[int, int], tuple[int, np.ndarray, np.ndarray]] = {}
        self.cast = 0                                # views cast (the rest were remembered)

    def seen_from(self, local_map: LocalMap, sight: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """The window cells visible from any of `cells` (rows of window i, j), as a mask.
        `sight` is the layer of local_map's latest layers()."""
        changes = local_map.sight_changes
        seen = np.zeros(sight.shape, bool)
        kept: dict[tuple[int, int], tuple[int, np.ndarray, np.ndarray]] = {}
        m = self._margin
        for i, j in cells:
            i, j = int(i), int(j)
            key = (local_map.row0 + i, local_map.col0 + j)
            view = kept.get(key) or self._views.get(key)
            if view is None or not changes.unchanged_since(view[0], i - m, i + m + 1, j - m, j + m + 1):
                one = np.zeros(sight.shape, bool)
                kernels.mark_visible(sight, np.array([i], np.int64), np.array([j], np.int64), self.n_rays,
                                     self.reach_cells, one)
                rows, cols = np.nonzero(one)
                view = (changes.epoch, rows + local_map.row0, cols + local_map.col0)
                self.cast += 1
            kept[key] = view
            seen[view[1] - local_map.row0, view[2] - local_map.col0] = True
        self._views = kept
        return seen

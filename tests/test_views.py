"""Views from places, remembered between planning cycles (services.views.ViewCache), equal
the rays cast afresh every time, while the map changes under them and the window moves."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.services.local_map import LocalMap
from firmware.services.views import ViewCache

P = ExplorationParams()
RAYS, REACH = 120, 30.0


def _paint_random(local_map: LocalMap, rng: np.random.Generator, blobs: int) -> None:
    """Walls and free space in random rectangles: some cells change state."""
    n = local_map.n
    for _ in range(blobs):
        i, j = (int(v) for v in rng.integers(0, n - 8, 2))
        h, w = (int(v) for v in rng.integers(1, 8, 2))
        local_map.logodds[i:i + h, j:j + w] = rng.choice([P.logodds_min, P.logodds_max, 0.0])


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_remembered_views_equal_fresh_casts_through_changes_and_moves(seed):
    rng = np.random.default_rng(seed)
    local_map = LocalMap(P, 20.0, 20.0)
    _paint_random(local_map, rng, 300)
    cache = ViewCache(RAYS, REACH)
    places_xy = rng.uniform(0.0, 40.0, (8, 2))
    for cycle in range(6):
        if cycle and rng.random() < 0.4:
            local_map.follow(*rng.uniform(16.0, 24.0, 2))            # the window moves (or not)
        if rng.random() < 0.7:
            _paint_random(local_map, rng, int(rng.integers(1, 4)))   # a few cells change
        sight = local_map.layers().sight
        ij, inside = local_map.cells_of(places_xy[rng.random(len(places_xy)) < 0.8])
        fresh = np.zeros(sight.shape, bool)
        kernels.mark_visible(sight, ij[inside, 0], ij[inside, 1], RAYS, REACH, fresh)
        np.testing.assert_array_equal(cache.seen_from(local_map, sight, ij[inside]), fresh)


def test_a_view_nothing_changed_around_is_not_cast_again():
    local_map = LocalMap(P, 20.0, 20.0)
    local_map.logodds[:] = P.logodds_min
    cache = ViewCache(RAYS, REACH)
    cells = np.array([[200, 200], [150, 250]])
    for _ in range(3):
        cache.seen_from(local_map, local_map.layers().sight, cells)
    assert cache.cast == 2
    local_map.logodds[200, 210] = P.logodds_max                  # a wall appears near the first
    cache.seen_from(local_map, local_map.layers().sight, cells)
    assert cache.cast == 3

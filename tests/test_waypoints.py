"""The waypoint scoring's shortcuts give what the plain computation gives, bit for bit."""
from types import SimpleNamespace

import numpy as np
from hypothesis import given, settings, strategies as st

from firmware import kernels
from firmware.services.waypoints import ObservableUnknownMemo

SETTINGS = settings(max_examples=60, deadline=None)


@st.composite
def states(draw, rows=st.integers(1, 45), cols=st.integers(1, 45), values=(0, 1, 2, 3)):
    r, c = draw(rows), draw(cols)
    cells = draw(st.lists(st.sampled_from(values), min_size=r * c, max_size=r * c))
    return np.array(cells, np.uint8).reshape(r, c)


@SETTINGS
@given(states(rows=st.integers(1, 40), cols=st.integers(1, 40), values=[0, 0, 1, 1, 1, 1, 1, 1, 1, 2, 3]),
       st.integers(1, 64), st.floats(0.0, 30.0), st.data())
def test_remembered_counts_equal_a_fresh_ray_cast_as_the_map_changes_and_the_window_moves(
        state, n_rays, max_range_cells, data):
    memo = ObservableUnknownMemo(n_rays, max_range_cells)
    window = SimpleNamespace(row0=0, col0=0)
    k = data.draw(st.integers(1, 12))
    rows = np.array(data.draw(st.lists(st.integers(0, state.shape[0] - 1), min_size=k, max_size=k)), np.int64)
    cols = np.array(data.draw(st.lists(st.integers(0, state.shape[1] - 1), min_size=k, max_size=k)), np.int64)
    for _ in range(data.draw(st.integers(1, 6))):
        state = state.copy()
        for _ in range(data.draw(st.integers(0, 20))):
            state[data.draw(st.integers(0, state.shape[0] - 1)), data.draw(st.integers(0, state.shape[1] - 1))] = \
                data.draw(st.sampled_from([0, 1, 2, 3]))
        if data.draw(st.integers(0, 3)) == 0:
            window = SimpleNamespace(row0=window.row0 + data.draw(st.integers(-3, 3)), col0=window.col0)
        np.testing.assert_array_equal(memo.counts(window, state, rows, cols),
                                      kernels.observable_unknown(state, rows, cols, n_rays, max_range_cells))

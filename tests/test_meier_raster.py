"""The coarse lattice the polygons live on (firmware.schemes.meier.raster): pooling the own
map into a monotone raster, and rings back into cells."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from firmware import kernels
from firmware.schemes.meier.contours import WALL_EDGE, trace_contours
from firmware.schemes.meier.raster import CoarseRaster, pool, rasterise_rings

U, F, O = kernels.UNKNOWN, kernels.FREE, kernels.OCCUPIED


def test_a_coarse_cell_is_free_with_half_its_cells_free_and_none_occupied():
    fine = np.array([[F, F, F, U, O, F],
                     [U, U, F, U, F, F]], np.uint8)
    coarse, r0, c0 = pool(fine, 0, 0, 2)
    assert (r0, c0) == (0, 0) and coarse.tolist() == [[F, F, O]]


def test_pooling_follows_the_global_lattice_whatever_the_grid_anchor():
    fine = np.full((3, 3), F, np.uint8)
    coarse, r0, c0 = pool(fine, 1, -1, 2)        # rows 1..3, columns -1..1
    assert (r0, c0) == (0, -1)
    # Global blocks: rows {0,1}, {2,3} x columns {-2,-1}, {0,1}: only 1, 2 or 4 cells of the grid.
    assert coarse.tolist() == [[U, F], [F, F]]


def test_the_own_raster_never_forgets_a_known_cell():
    raster = CoarseRaster(2)
    raster.merge(np.full((4, 4), F, np.uint8), 0, 0)
    raster.merge(np.full((4, 4), U, np.uint8), 0, 0)            # nothing seen there now
    raster.merge(np.array([[O, O, U, U]] * 4, np.uint8), 0, 0)  # a wall where it was free
    raster.merge(np.full((2, 2), F, np.uint8), 100, -100)       # far away: the raster grows
    cells = raster.cells
    at = lambda r, c: int(cells[r - raster.row0, c - raster.col0])   # noqa: E731
    assert [at(0, 0), at(0, 1), at(1, 1), at(50, -50), at(10, 10)] == [O, F, F, F, U]


@settings(max_examples=60, deadline=None)
@given(st.integers(3, 25), st.integers(3, 25), st.data())
def test_the_rings_of_every_contour_give_back_the_free_cells_and_the_walls_beside_them(rows, cols, data):
    cells = data.draw(st.lists(st.sampled_from([U, F, O]), min_size=rows * cols, max_size=rows * cols))
    state = np.array(cells, np.uint8).reshape(rows, cols)
    contours = trace_contours(state)
    row0, col0 = data.draw(st.integers(-50, 50)), data.draw(st.integers(-50, 50))
    rings = [c.corners + (col0, row0) for c in contours]
    walls = [c.edge_types == WALL_EDGE for c in contours]
    got = rasterise_rings(rings, walls, state.shape, row0, col0)
    free = state == F
    beside = np.zeros_like(free)
    beside[1:, :] |= free[:-1, :]
    beside[:-1, :] |= free[1:, :]
    beside[:, 1:] |= free[:, :-1]
    beside[:, :-1] |= free[:, 1:]
    expected = np.full(state.shape, U, np.uint8)
    expected[free] = F
    expected[(state == O) & beside] = O
    np.testing.assert_array_equal(got, expected)


def test_rings_far_outside_the_grid_cost_nothing_and_draw_nothing():
    ring = np.array([[-16000, -16000], [16000, -16000], [16000, 16000]], np.int64)
    got = rasterise_rings([ring], [np.ones(3, bool)], (20, 30), -120, 100)
    assert (got == F).all()                                      # inside the huge triangle, far from its edges
    got = rasterise_rings([ring + 40000], [np.ones(3, bool)], (20, 30), 100, 100)
    assert (got == U).all()


def test_a_hole_is_cut_out_of_the_free_area_unknown_inside_and_walled_if_its_edges_are():
    room = np.array([[0, 0], [20, 0], [20, 20], [0, 20]], np.int64)            # counter-clockwise
    small = np.array([[5, 5], [5, 7], [7, 7], [7, 5]], np.int64)               # clockwise: 4 cells
    frontier = [np.zeros(4, bool)] * 2
    got = rasterise_rings([room, small], frontier, (20, 20), 0, 0)
    assert (got[5:7, 5:7] == U).all() and got[4, 4] == F and got[7, 7] == F
    walled = rasterise_rings([room, small], [np.zeros(4, bool), np.ones(4, bool)], (20, 20), 0, 0)
    assert (walled[5:7, 5:7] == O).all()

"""A receiver's copy of a teammate's polygons against the original (host_tools/polygon_metrics.py):
the share of the area the original says something about that the copy draws otherwise, and
the share of its vertices the copy does not hold exactly."""
from types import SimpleNamespace

import pytest

from host_tools.polygon_metrics import replica_mismatch

WALL, FRONTIER = 1, 0
# A 10 x 10 lattice square (walls on three sides, a frontier on top), vertices 1..4.
SQUARE = [[(1, 0, 0, WALL), (2, 10, 0, WALL), (3, 10, 10, FRONTIER), (4, 0, 10, WALL)]]


def _team(sent, held):
    """Two robots: robot 0 sends `sent`, robot 1 holds `held` of it (and sends nothing)."""
    def agent(rid, own, copies):
        scheme = SimpleNamespace(polygons=lambda: own, polygons_of=lambda sender: copies.get(sender, []))
        return SimpleNamespace(hal=SimpleNamespace(robot_id=rid), scheme=scheme)
    return [agent(0, sent, {}), agent(1, [], {0: held})]


def test_an_exact_copy_differs_in_nothing_and_a_missing_one_in_everything():
    area, vertices = replica_mismatch(_team(SQUARE, SQUARE))
    assert area == [[None, None], [0.0, None]] and vertices == [[None, None], [0.0, None]]
    area, vertices = replica_mismatch(_team(SQUARE, []))
    assert area[1][0] == 1.0 and vertices[1][0] == 1.0


def test_a_copy_with_one_corner_cut_off_differs_by_the_area_of_that_corner():
    cut = [[(1, 0, 0, WALL), (2, 10, 0, WALL), (3, 10, 10, FRONTIER), (5, 5, 10, WALL), (6, 0, 5, WALL)]]
    area, vertices = replica_mismatch(_team(SQUARE, cut))
    # Originally 100 cells free plus the wall bands (10 below, 10 right, 10 left: 30) known.
    # The copy loses the top left triangle (12.5 cells, drawn as 15 by cell centres) and
    # draws a wall band along its cut instead of the left wall's upper half.
    assert 0.05 < area[1][0] < 0.3
    assert vertices[1][0] == pytest.approx(2 / 4)       # 3's successor and 4 are wrong

"""WiSER-X's A30 option (`--set wiserx.nlos_from_map=true`): a range or bearing taken while the
own map shows walls between the robot and the track's prediction counts with more noise."""
from __future__ import annotations

import math

import numpy as np
import pytest

from firmware import kernels
from firmware.schemes.wiserx.ekf import TeammateEkf
from firmware.schemes.wiserx.params import EkfParams
from firmware.schemes.wiserx.relpos import RelPos, polar_fix
from firmware.services.grid_paths import walls_crossed
from hal.samples import UwbRange


def _room_with_walls() -> np.ndarray:
    state = np.full((20, 40), kernels.FREE, np.uint8)
    state[:, 10:12] = kernels.OCCUPIED             # one wall two cells thick
    state[:, 25] = kernels.OCCUPIED                # a second wall
    return state


@pytest.mark.parametrize("j1, walls", [(5, 0), (10, 1), (20, 1), (30, 2), (39, 2), (400, 2)])
def test_walls_are_counted_as_runs_of_wall_cells_up_to_the_grid_edge(j1, walls):
    assert walls_crossed(_room_with_walls(), 10, 0, 10, j1) == walls


def test_a_diagonal_segment_counts_the_walls_it_crosses():
    assert walls_crossed(_room_with_walls(), 0, 0, 19, 39) == 2
    assert walls_crossed(_room_with_walls(), 0, 12, 19, 24) == 0


def test_noise_grows_with_the_walls_in_between():
    p = EkfParams(range_std_m=0.1, bearing_std_rad=0.05, nlos_range_std_per_wall_m=0.3, nlos_bearing_std_factor=2.0)
    assert p.noise(0) == (0.1, 0.05)
    assert p.noise(2) == pytest.approx((0.7, 0.1))
    _, R0 = polar_fix(10.0, 0.0, (0.0, 0.0), p)
    _, R2 = polar_fix(10.0, 0.0, (0.0, 0.0), p, walls=2)
    assert R2[0, 0] == pytest.approx(0.49) and R2[1, 1] == pytest.approx(4 * R0[1, 1])


def test_a_range_behind_walls_moves_the_track_less():
    moved = []
    for walls in (0, 3):
        ekf = TeammateEkf(EkfParams())
        ekf.start(0, (0.0, 0.0), 10.0, 0.0)
        ekf.observe(100_000, (0.0, 0.0), range_m=10.4, walls=walls)
        moved.append(ekf.position[0] - 10.0)
    assert 0.0 < moved[1] < moved[0] / 3


def test_relpos_asks_for_the_walls_between_the_robot_and_the_prediction():
    asked = []

    def walls_between(own_xy, teammate_xy):
        asked.append((own_xy, tuple(round(v, 6) for v in teammate_xy)))
        return 1

    rp = RelPos(0)
    track = rp.track(1)
    track.ekf.start(0, (0.0, 0.0), 5.0, math.pi / 2)        # teammate at (0, 5), standing
    rp.feed([UwbRange(200_000, 1, 5.0)], [], lambda stamp_us: (1.0, 0.0, 0.0), walls_between)
    assert asked == [((1.0, 0.0), (0.0, 5.0))]

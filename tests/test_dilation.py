"""firmware/services/dilation.py equals scipy's binary_dilation with the same structure."""
import numpy as np
import pytest
import scipy.ndimage as ndimage

from firmware.services.dilation import dilate_disc, dilate_square


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("size", [1, 2, 3, 4, 7])
def test_square_and_disc_equal_binary_dilation(seed, size):
    rng = np.random.default_rng(seed)
    mask = rng.random((37 + seed, 53)) < 0.03
    mask[0, 5] = mask[-1, -1] = True                  # at the edges too
    square = np.ones((2 * size + 1,) * 2, bool)
    yy, xx = np.mgrid[-size:size + 1, -size:size + 1]
    assert (dilate_square(mask, size) == ndimage.binary_dilation(mask, structure=square)).all()
    assert (dilate_disc(mask, size) == ndimage.binary_dilation(mask, structure=yy * yy + xx * xx <= size * size)).all()


def test_an_empty_mask_stays_empty():
    assert not dilate_disc(np.zeros((5, 6), bool), 4).any() and not dilate_square(np.zeros((5, 6), bool), 1).any()

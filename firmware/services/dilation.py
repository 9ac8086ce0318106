"""Binary dilation by a square or a disc of whole cells, as separable maximum filters:
scipy's binary_dilation visits every cell of the structure for every cell of the mask, and
a frontier search over everything a robot has mapped dilates it three times.

Both equal ndimage.binary_dilation with the same structure and its default border (cells
beyond the edge are False); tests/test_dilation.py checks it on random masks.
"""
from __future__ import annotations

import math

import numpy as np
import scipy.ndimage as ndimage


def dilate_box(mask: np.ndarray, half_rows: int, half_cols: int) -> np.ndarray:
    """The cells within half_rows rows and half_cols columns of a True cell."""
    out = mask.astype(np.uint8)
    if half_rows > 0:
        out = ndimage.maximum_filter1d(out, 2 * half_rows + 1, axis=0, mode="constant", cval=0)
    if half_cols > 0:
        out = ndimage.maximum_filter1d(out, 2 * half_cols + 1, axis=1, mode="constant", cval=0)
    return out.view(bool)


def dilate_square(mask: np.ndarray, half_cells: int) -> np.ndarray:
    """binary_dilation(mask, np.ones((2 h + 1, 2 h + 1)))."""
    return dilate_box(mask, half_cells, half_cells)


def dilate_disc(mask: np.ndarray, radius_cells: int) -> np.ndarray:
    """binary_dilation(mask, di * di + dj * dj <= r * r over offsets -r..r): the disc as the
    union of the boxes |di| <= k, |dj| <= isqrt(r * r - k * k), one for each k where the
    disc's half-width steps down."""
    r = radius_cells
    widths = [math.isqrt(r * r - k * k) for k in range(r + 1)]
    out = np.zeros(mask.shape, bool)
    for k, w in enumerate(widths):
        if k == r or widths[k + 1] < w:
            out |= dilate_box(mask, k, w)
    return out

"""The body-fit layers kept across planning cycles equal the layers derived from scratch,
whatever changed between cycles and however the window moved."""
import numpy as np
from hypothesis import given, settings, strategies as st

from firmware import kernels
from firmware.params import ExplorationParams
from firmware.services.body_fit import BodyFit

P = ExplorationParams()
N = 256   # window side (cells): 8 x 8 tiles, small enough for many examples


def _rooms(rng: np.random.Generator) -> np.ndarray:
    """A known patch of free rooms with walls, doors of random widths, clutter, unknown
    pockets; the rest of the window unknown."""
    state = np.zeros((N, N), np.uint8)
    i0, j0 = rng.integers(0, N // 3, 2)
    i1, j1 = rng.integers(2 * N // 3, N, 2)
    state[i0:i1, j0:j1] = kernels.FREE
    for _ in range(rng.integers(2, 8)):
        if rng.random() < 0.5:
            r = rng.integers(i0, i1)
            state[r, j0:j1] = kernels.OCCUPIED
            door = rng.integers(j0, j1)
            state[r, door:door + rng.integers(3, 9)] = kernels.FREE
        else:
            c = rng.integers(j0, j1)
            state[i0:i1, c] = kernels.OCCUPIED
            door = rng.integers(i0, i1)
            state[door:door + rng.integers(3, 9), c] = kernels.FREE
    clutter = rng.random((N, N)) < 0.01
    state[clutter & (state == kernels.FREE)] = kernels.OCCUPIED
    pockets = rng.random((N, N)) < 0.01
    state[pockets & (state == kernels.FREE)] = kernels.UNKNOWN
    return state


def _edit(rng: np.random.Generator, state: np.ndarray) -> np.ndarray:
    """What a few scans do between two cycles: patches become known, free or walled."""
    out = state.copy()
    for _ in range(rng.integers(0, 4)):
        i, j = rng.integers(0, N, 2)
        h, w = rng.integers(1, 20, 2)
        patch = out[i:i + h, j:j + w]
        patch[...] = rng.choice([kernels.FREE, kernels.OCCUPIED, kernels.UNKNOWN], p=[0.7, 0.2, 0.1], size=patch.shape)
    return out


def _shift(state: np.ndarray, di: int, dj: int) -> np.ndarray:
    """The same world seen from a window whose cell (0, 0) moved by (di, dj); cells new to
    the window are unknown."""
    out = np.zeros_like(state)
    i0, i1 = max(0, -di), min(N, N - di)
    j0, j1 = max(0, -dj), min(N, N - dj)
    if i0 < i1 and j0 < j1:
        out[i0:i1, j0:j1] = state[i0 + di:i1 + di, j0 + dj:j1 + dj]
    return out


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), tight=st.booleans())
def test_kept_layers_equal_layers_from_scratch(seed, tight):
    rng = np.random.default_rng(seed)
    kept = BodyFit(P, tight)
    state = _rooms(rng)
    row0 = col0 = 0
    for _cycle in range(6):
        if rng.random() < 0.3:
            di, dj = (int(v) for v in rng.integers(-40, 41, 2))
            state = _shift(state, di, dj)
            row0, col0 = row0 + di, col0 + dj
        state = _edit(rng, state)
        got = kept.update(state, row0, col0)
        want = BodyFit(P, tight).update(state, row0, col0)
        for name, a, b in zip(got._fields, got, want):
            assert np.array_equal(a, b), name

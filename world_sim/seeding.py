"""One random stream per component and robot, all derived from the mission seed.

Streams are keyed by a stable name, not by creation order, so adding a sensor never shifts
the numbers another component draws (the Gymnasium / SeedSequence discipline).
"""
from __future__ import annotations

import zlib

import numpy as np


def stream(seed: int, component: str, index: int = 0) -> np.random.Generator:
    """The generator for `component` (e.g. "lidar", "uwb", "radio.channel") of robot `index`."""
    key = (zlib.crc32(component.encode("utf-8")), int(index))
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed), spawn_key=key)))

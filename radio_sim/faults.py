"""Injected link faults: losses, bit corruption and duplicated frames, on top of the channel
physics. They exercise the firmware's CRC check and duplicate suppression."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FaultParams:
    loss_probability: float = 0.0
    # A corrupted frame arrives with 1..3 payload bits flipped, as if the PHY CRC had missed
    # it: the frame's own CRC must catch it.
    corruption_probability: float = 0.0
    duplication_probability: float = 0.0
    # A duplicate becomes due this long after the original's end; it is handed over at the
    # first moment from then on that the receiver is armed (one-shot, like a real frame).
    duplicate_delay_us: int = 5_000

    def __post_init__(self) -> None:
        for name in ("loss_probability", "corruption_probability", "duplication_probability"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0.0 <= value <= 1.0):
                raise ValueError(f"FaultParams.{name} must be a probability in [0, 1], got {value!r}")
        if not isinstance(self.duplicate_delay_us, int) or self.duplicate_delay_us < 0:
            raise ValueError(f"FaultParams.duplicate_delay_us must be an int >= 0, got {self.duplicate_delay_us!r}")

    @property
    def any(self) -> bool:
        return self.loss_probability > 0 or self.corruption_probability > 0 or self.duplication_probability > 0


@dataclass(frozen=True)
class FaultDraw:
    lost: bool
    corrupted: bool
    duplicated: bool


NO_FAULT = FaultDraw(False, False, False)


def draw_faults(params: FaultParams, rng: np.random.Generator) -> FaultDraw:
    """Three uniforms per candidate reception, always, so that changing one probability does
    not shift which receptions the other two faults hit."""
    u_loss, u_corrupt, u_dup = rng.random(3)
    lost = bool(u_loss < params.loss_probability)
    corrupted = (not lost) and bool(u_corrupt < params.corruption_probability)
    duplicated = (not lost) and (not corrupted) and bool(u_dup < params.duplication_probability)
    return FaultDraw(lost, corrupted, duplicated)


def flip_bits(payload: bytes, rng: np.random.Generator) -> bytes:
    """`payload` with 1..3 distinct random bits flipped (fewer if it has fewer bits)."""
    n_bits = 8 * len(payload)
    if n_bits == 0:
        return payload
    count = int(rng.integers(1, 4))
    positions = rng.choice(n_bits, size=min(count, n_bits), replace=False)
    out = bytearray(payload)
    for bit in sorted(int(p) for p in positions):
        out[bit // 8] ^= 1 << (bit % 8)
    return bytes(out)

"""What happened to each frame on the air: the record the channel emits for captures,
the packet inspector and the metrics."""
from __future__ import annotations

from dataclasses import dataclass

# Fates of one frame at one receiver.
RECEIVED = "received"
COLLIDED = "collided"
OUT_OF_RANGE = "out_of_range"
CORRUPTED = "corrupted"        # delivered with flipped bits (injected); the frame CRC catches it
INJECTED_LOSS = "injected_loss"
HALF_DUPLEX = "half_duplex"    # the receiver was transmitting
NOT_LISTENING = "not_listening"  # the receiver's modem was not in receive mode
FATES = (RECEIVED, COLLIDED, OUT_OF_RANGE, CORRUPTED, INJECTED_LOSS, HALF_DUPLEX, NOT_LISTENING)


@dataclass(frozen=True)
class Reception:
    receiver_id: int
    rssi_dbm: float
    snr_db: float
    fate: str


@dataclass(frozen=True)
class AirFrame:
    start_us: int
    end_us: int
    sender_id: int
    freq_hz: int
    sf: int
    bw_hz: int
    payload: bytes
    receptions: tuple[Reception, ...]

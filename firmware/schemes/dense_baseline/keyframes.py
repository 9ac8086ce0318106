"""The dense baselines' keyframe: the scan at a topological vertex, binned to fixed world
bearings, as one message on the mesh link (its one wire format)."""
from __future__ import annotations

import math
import struct

import numpy as np

from firmware.services.local_map import BinnedScan

# A keyframe on the mesh link: sender u8, x_cm i32, y_cm i32, bearing of the first bin u16
# (in 1/65536 of a turn), range_max_cm u16, bins u16, then one u16 range in cm per bin
# (little-endian): 15 + 2 * bins bytes.
_KEYFRAME_HEAD = struct.Struct("<BiiHHH")
_TURN_UNITS = 65536


def keyframe_bytes(bins: int) -> int:
    return _KEYFRAME_HEAD.size + 2 * bins


def encode_keyframe(sender_id: int, scan: BinnedScan) -> bytes:
    ranges_cm = np.clip(np.round(scan.ranges_m * 100.0), 0, 65535).astype("<u2")
    bearing0 = round(scan.bearing0_rad % (2 * math.pi) / (2 * math.pi) * _TURN_UNITS) % _TURN_UNITS
    return _KEYFRAME_HEAD.pack(sender_id, round(scan.x_m * 100), round(scan.y_m * 100), bearing0,
                               min(65535, round(scan.range_max_m * 100)), len(ranges_cm)) + ranges_cm.tobytes()


def decode_keyframe(data: bytes) -> tuple[int, BinnedScan] | None:
    """(sender, scan), or None if malformed."""
    if len(data) < _KEYFRAME_HEAD.size:
        return None
    sender, x_cm, y_cm, bearing0, range_max_cm, bins = _KEYFRAME_HEAD.unpack_from(data)
    if bins == 0 or len(data) != keyframe_bytes(bins) or range_max_cm == 0:
        return None
    ranges = np.frombuffer(data, "<u2", bins, _KEYFRAME_HEAD.size).astype(np.float64) / 100.0
    return sender, BinnedScan(x_cm / 100.0, y_cm / 100.0, bearing0 * (2 * math.pi / _TURN_UNITS),
                              ranges, range_max_cm / 100.0)

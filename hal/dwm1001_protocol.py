"""The Qorvo (Decawave) DWM1001 UART generic API (TLV), in one place: request and response
types, return codes, value layouts, and a response reader. The driver (hal.dwm1001) and the
emulator (world_sim.devices.dwm1001_emulator) both take them from here. Pure: no I/O, no clock.

Source: Decawave "DWM1001 Firmware API Guide" (PANS), sections on the UART generic API and
dwm_loc_get, dwm_status_get, dwm_cfg_get, dwm_ver_get, and Decawave's host API (dwm_api.c).
115200 8N1. The module also has a text shell (`les`, `lec` ...), entered with two CRs; this
project uses the TLV API instead, because it is binary and fixed-layout (no parsing of
prose), answers every request with a return code, and is the interface Decawave's own host
library speaks; the shell's output format changes between firmware releases.

Frames are type (u8), length (u8), value (length bytes). The host sends one request; the
module answers with a return-value TLV `40 01 rc` and, when rc is 0, the request's data
TLVs in a fixed order. Integers are little-endian; positions and distances are millimetres.

dwm_loc_get (`0C 00`) answers:
- `41 0D` the node's own position: x, y, z (i32 mm) and a quality factor (u8, 0..100);
- a tag: `49 len` count (u8) and per anchor: address (u16), distance (u32 mm), quality
  (u8), the anchor's configured position (13 bytes as above); at most 4 anchors;
- an anchor: `48 len` count and per tag: address (u64), distance (u32 mm), quality (u8);
  at most 15 tags.
dwm_status_get (`32 00`) answers `5A 02` status (u16): bit 0 new location data since the last
dwm_loc_get, bit 1 joined the UWB network (one byte on older firmware).
"""
from __future__ import annotations

import struct
from collections import deque
from dataclasses import dataclass

BAUDRATE = 115200

# -- requests (host -> module) -------------------------------------------------------------
CMD_POS_SET = 0x01
CMD_POS_GET = 0x02
CMD_UR_SET = 0x03
CMD_UR_GET = 0x04
CMD_CFG_TN_SET = 0x05
CMD_CFG_AN_SET = 0x07
CMD_CFG_GET = 0x08
CMD_LOC_GET = 0x0C
CMD_RESET = 0x14
CMD_VER_GET = 0x15
CMD_STATUS_GET = 0x32

# -- response TLV types (module -> host) ----------------------------------------------------
TLV_RET_VAL = 0x40
TLV_POS_XYZ = 0x41
TLV_UR = 0x45
TLV_CFG = 0x46
TLV_RNG_AN_DIST = 0x48          # an anchor's distances to tags
TLV_RNG_AN_POS_DIST = 0x49      # a tag's distances to anchors, with their positions
TLV_FW_VER = 0x50
TLV_CFG_VER = 0x51
TLV_HW_VER = 0x52
TLV_STATUS = 0x5A

# -- return codes ------------------------------------------------------------------------------
RV_OK = 0
RV_ERR_TLV = 1                  # unknown command or broken TLV frame
RV_ERR_INTERNAL = 2
RV_ERR_INVAL_PARAM = 3
RV_ERR_BUSY = 4
RV_ERR_PERMISSION = 5
RETURN_CODES = {RV_OK: "ok", RV_ERR_TLV: "unknown command or broken TLV frame", RV_ERR_INTERNAL: "internal error",
                RV_ERR_INVAL_PARAM: "invalid parameter", RV_ERR_BUSY: "busy", RV_ERR_PERMISSION: "operation not permitted"}

STATUS_LOC_READY = 0x0001
STATUS_UWBMAC_JOINED = 0x0002
CFG_MODE_ANCHOR_BIT = 5         # in the configuration's second byte: 0 tag, 1 anchor

TAG_MAX_ANCHORS = 4             # a PANS tag ranges to at most four anchors per update
ANCHOR_MAX_TAGS = 15
POSITION_BYTES = 13
TAG_ENTRY_BYTES = 2 + 4 + 1 + POSITION_BYTES
ANCHOR_ENTRY_BYTES = 8 + 4 + 1
QUALITY_MAX = 100
MAX_VALUE_BYTES = 253           # a whole frame fits the module's 255-byte buffer

# The emulated team's address plan: robot r's module answers to ADDRESS_BASE + r. (Real
# modules take their short address from the chip's id; a real team lists them.)
ADDRESS_BASE = 0x1000


def robot_address(robot_id: int) -> int:
    return ADDRESS_BASE + robot_id


def default_peer_ids(robots: int = 256) -> dict[int, int]:
    """UWB short address -> robot id under the emulated team's plan."""
    return {robot_address(r): r for r in range(robots)}

# The data TLVs each request is answered with when rc is 0, in order (a set of the types
# allowed at each place). Requests not listed answer with the return value alone.
ANSWER_TLVS: dict[int, tuple[frozenset[int], ...]] = {
    CMD_POS_GET: (frozenset({TLV_POS_XYZ}),),
    CMD_UR_GET: (frozenset({TLV_UR}),),
    CMD_CFG_GET: (frozenset({TLV_CFG}),),
    CMD_LOC_GET: (frozenset({TLV_POS_XYZ}), frozenset({TLV_RNG_AN_DIST, TLV_RNG_AN_POS_DIST})),
    CMD_VER_GET: (frozenset({TLV_FW_VER}), frozenset({TLV_CFG_VER}), frozenset({TLV_HW_VER})),
    CMD_STATUS_GET: (frozenset({TLV_STATUS}),),
}
# Value lengths of the fixed-size TLVs (the status grew from one byte to two in PANS R2).
FIXED_LENGTHS: dict[int, tuple[int, ...]] = {
    TLV_POS_XYZ: (POSITION_BYTES,), TLV_UR: (4,), TLV_CFG: (2,), TLV_FW_VER: (4,), TLV_CFG_VER: (4,),
    TLV_HW_VER: (4,), TLV_STATUS: (1, 2),
}
# Value lengths each request takes (absent: the request is not one this project knows).
REQUEST_LENGTHS: dict[int, int] = {
    CMD_POS_SET: POSITION_BYTES, CMD_POS_GET: 0, CMD_UR_SET: 4, CMD_UR_GET: 0, CMD_CFG_TN_SET: 2,
    CMD_CFG_AN_SET: 2, CMD_CFG_GET: 0, CMD_LOC_GET: 0, CMD_RESET: 0, CMD_VER_GET: 0, CMD_STATUS_GET: 0,
}


def tlv(tlv_type: int, value: bytes = b"") -> bytes:
    if len(value) > MAX_VALUE_BYTES:
        raise ValueError(f"TLV 0x{tlv_type:02X}: {len(value)} bytes do not fit one frame")
    return bytes((tlv_type, len(value))) + value


def request(cmd: int, value: bytes = b"") -> bytes:
    return tlv(cmd, value)


def return_value(rc: int) -> bytes:
    return tlv(TLV_RET_VAL, bytes((rc,)))


# -- values ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Position:
    x_mm: int = 0
    y_mm: int = 0
    z_mm: int = 0
    quality: int = 0              # 0: unknown

    def encode(self) -> bytes:
        return struct.pack("<iiiB", self.x_mm, self.y_mm, self.z_mm, self.quality)

    @classmethod
    def decode(cls, value: bytes) -> Position:
        return cls(*struct.unpack("<iiiB", value[:POSITION_BYTES]))


@dataclass(frozen=True)
class Distance:
    """One ranging result: to an anchor (the node is a tag) or to a tag (it is an anchor)."""

    address: int                  # u16 short address (a tag's report) or u64 (an anchor's)
    distance_mm: int
    quality: int
    position: Position | None = None      # the anchor's configured position (tag reports only)


@dataclass(frozen=True)
class Location:
    """What dwm_loc_get reports."""

    position: Position
    distances: tuple[Distance, ...]
    node_is_anchor: bool


def encode_location(loc: Location) -> bytes:
    """The data TLVs of a dwm_loc_get answer (after the return value)."""
    if loc.node_is_anchor:
        if len(loc.distances) > ANCHOR_MAX_TAGS:
            raise ValueError(f"an anchor reports at most {ANCHOR_MAX_TAGS} tags, got {len(loc.distances)}")
        entries = b"".join(struct.pack("<QIB", d.address, d.distance_mm, d.quality) for d in loc.distances)
        ranges = tlv(TLV_RNG_AN_DIST, bytes((len(loc.distances),)) + entries)
    else:
        if len(loc.distances) > TAG_MAX_ANCHORS:
            raise ValueError(f"a tag reports at most {TAG_MAX_ANCHORS} anchors, got {len(loc.distances)}")
        entries = b"".join(struct.pack("<HIB", d.address, d.distance_mm, d.quality)
                           + (d.position or Position()).encode() for d in loc.distances)
        ranges = tlv(TLV_RNG_AN_POS_DIST, bytes((len(loc.distances),)) + entries)
    return tlv(TLV_POS_XYZ, loc.position.encode()) + ranges


def decode_location(tlvs: dict[int, bytes]) -> Location:
    """A dwm_loc_get answer's TLVs (as ResponseReader checked them) as a Location."""
    position = Position.decode(tlvs[TLV_POS_XYZ])
    if TLV_RNG_AN_DIST in tlvs:
        value = tlvs[TLV_RNG_AN_DIST]
        distances = tuple(Distance(*struct.unpack_from("<QIB", value, 1 + k * ANCHOR_ENTRY_BYTES))
                          for k in range(value[0]))
        return Location(position, distances, node_is_anchor=True)
    value = tlvs[TLV_RNG_AN_POS_DIST]
    distances = []
    for k in range(value[0]):
        at = 1 + k * TAG_ENTRY_BYTES
        address, distance_mm, quality = struct.unpack_from("<HIB", value, at)
        distances.append(Distance(address, distance_mm, quality, Position.decode(value[at + 7:at + TAG_ENTRY_BYTES])))
    return Location(position, tuple(distances), node_is_anchor=False)


def encode_status(status: int) -> bytes:
    return tlv(TLV_STATUS, struct.pack("<H", status))


def decode_status(value: bytes) -> int:
    return int.from_bytes(value, "little")


def encode_cfg(node_is_anchor: bool) -> bytes:
    """A configuration as the module reports it: UWB active, BLE, LEDs and firmware update
    on, location engine on for a tag, two-way ranging, no stationary detection."""
    uwb_mode_active = 2
    common = uwb_mode_active | (1 << 2) | (1 << 3) | (1 << 4)
    first = common | (0 if node_is_anchor else 1 << 6)
    second = (1 << CFG_MODE_ANCHOR_BIT) if node_is_anchor else 0
    return tlv(TLV_CFG, bytes((first, second)))


def cfg_is_anchor(value: bytes) -> bool:
    return bool(value[1] >> CFG_MODE_ANCHOR_BIT & 1)


# -- the host's response reader ---------------------------------------------------------------

@dataclass(frozen=True)
class Response:
    cmd: int                       # the request it answers
    rc: int
    tlvs: dict[int, bytes]


def _value_ok(tlv_type: int, value: bytes) -> bool:
    if tlv_type in FIXED_LENGTHS:
        return len(value) in FIXED_LENGTHS[tlv_type]
    entry = {TLV_RNG_AN_DIST: ANCHOR_ENTRY_BYTES, TLV_RNG_AN_POS_DIST: TAG_ENTRY_BYTES}[tlv_type]
    return len(value) >= 1 and len(value) == 1 + value[0] * entry


class ResponseReader:
    """Splits the module's bytes into answers to the requests the host sent, in order.

    The host tells it each request it sends (`expect`). Bytes before a return-value TLV are
    skipped; an answer whose data TLVs are not the ones its request is answered with, or
    whose lengths do not add up, is dropped and the search goes on from its next byte. Bytes
    nobody asked for are dropped. Never raises."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._expected: deque[int] = deque()
        self.bytes_skipped = 0
        self.malformed = 0

    def expect(self, cmd: int) -> None:
        self._expected.append(cmd)

    def forget(self) -> None:
        """Give up on every request still unanswered (after a timeout)."""
        self._expected.clear()
        self.bytes_skipped += len(self._buf)
        self._buf.clear()

    @property
    def waiting(self) -> int:
        return len(self._expected)

    def feed(self, data: bytes) -> list[Response]:
        self._buf += data
        out: list[Response] = []
        while self._buf:
            if not self._expected:
                self._skip(len(self._buf))
                break
            start = self._buf.find(bytes((TLV_RET_VAL, 1)))
            if start < 0:
                keep = 1 if self._buf[-1] == TLV_RET_VAL else 0
                self._skip(len(self._buf) - keep)
                break
            self._skip(start)
            answer, used = self._answer_at_head()
            if used == 0:
                break                         # incomplete: wait for more bytes
            if answer is None:
                self.malformed += 1
                self._skip(1)
                continue
            del self._buf[:used]
            self._expected.popleft()
            out.append(answer)
        return out

    def _answer_at_head(self) -> tuple[Response | None, int]:
        """(answer, bytes it used) for a return value at the head; (None, n > 0) if it is
        malformed; (None, 0) if more bytes are needed."""
        buf = self._buf
        if len(buf) < 3:
            return None, 0
        cmd, rc = self._expected[0], buf[2]
        if rc != RV_OK:
            return Response(cmd, rc, {}), 3
        at, tlvs = 3, {}
        for allowed in ANSWER_TLVS.get(cmd, ()):
            if len(buf) < at + 2:
                return None, 0
            tlv_type, length = buf[at], buf[at + 1]
            if tlv_type not in allowed:
                return None, 1
            if len(buf) < at + 2 + length:
                return None, 0
            value = bytes(buf[at + 2:at + 2 + length])
            if not _value_ok(tlv_type, value):
                return None, 1
            tlvs[tlv_type] = value
            at += 2 + length
        return Response(cmd, rc, tlvs), at

    def _skip(self, n: int) -> None:
        del self._buf[:n]
        self.bytes_skipped += n


# -- the module's request reader ----------------------------------------------------------------

@dataclass(frozen=True)
class Request:
    cmd: int
    value: bytes


class RequestReader:
    """The module's side: splits the host's bytes into requests. A type this project does
    not know, or a known one with the wrong length, cannot be framed: it is reported as a
    broken frame (None) and the bytes received so far are dropped, as the module drops a
    broken frame. Never raises."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[Request | None]:
        self._buf += data
        out: list[Request | None] = []
        while len(self._buf) >= 2:
            cmd, length = self._buf[0], self._buf[1]
            if REQUEST_LENGTHS.get(cmd) != length:
                out.append(None)
                self._buf.clear()
                break
            if len(self._buf) < 2 + length:
                break
            out.append(Request(cmd, bytes(self._buf[2:2 + length])))
            del self._buf[:2 + length]
        return out

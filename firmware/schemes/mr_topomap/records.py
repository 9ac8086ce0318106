"""MR-TopoMap's records on the air (mrtopomap.md 5.1): mrvtx, mredge, mrud, mrlink.

Dialect id 5 (Bayer & Faigl 1, Meier 2, Pereira 3; 4 is left for WiSER-X). The spec numbered
the records 4..7 when every record type lived in one table; with one dialect per scheme they
are codes 1..4 of this dialect, same fields, same sizes (30, 6, 6, 9 bytes). Registered
through the `mrtopomap` scheme: `firmware.schemes.all_dialects()` holds it, so every node
decodes it. The codec takes the RecordType objects below directly, so `encode_*`/`decode_*`
here work without the registry.

Positions are decimetres in the SENDER'S OWN odometry frame, not a shared mission frame:
16-bit signed (+-3276.7 m; quantisation <= 5 cm). Bit order inside the packed fields:
ud_sectors holds sector k (centred on k * 22.5 deg of the sender's frame) in bits 2k..2k+1
(sector 0 in the least significant pair); a clear_mask holds sector k in bit k; desc_i holds
the descriptor bins 8i..8i+7, bin 8i in the most significant nibble.

Decoding never raises: `decode_*` return (value, Reason, detail) with value None when the
bytes are refused (wrong length, non-zero padding, a field out of range).
"""
from __future__ import annotations

import math
from typing import NamedTuple

from firmware.comms import codec
from firmware.comms.codec import Reason
from firmware.comms.schema import SENDER, Dialect, Field, RecordType
from firmware.schemes.mr_topomap.descriptor import BINS, MEAN_CODES, STD_CODES, Descriptor

DIALECT_ID = 5

ID_BITS = 12
MAX_VERTEX_ID = (1 << ID_BITS) - 2          # 4094: ids 0..4094 (A19)
NO_VERTEX = (1 << ID_BITS) - 1              # 4095: "no edge" in prev_id (the first vertex)
SECTORS = 16                                # unexplored directions: 16 sectors of 22.5 deg (A10)
SECTOR_RAD = 2.0 * math.pi / SECTORS
DYAW_CODES = 1 << 12                        # mrlink yaw: 360 / 4096 = 0.088 deg
MAX_SUPPORT = (1 << 6) - 1
CODES_PER_WORD = 8                          # descriptor bins per 32-bit desc_i field

_DESC_WORDS = BINS // CODES_PER_WORD


def _dm(name: str, doc: str) -> Field:
    return Field(name, 16, True, "0.1 m", doc=doc)


def _vid(name: str, doc: str, none_ok: bool = False) -> Field:
    return Field(name, ID_BITS, unit="id", hi=NO_VERTEX if none_ok else MAX_VERTEX_ID, doc=doc)


MRVTX = RecordType(
    1, "mrvtx", 30,
    (
        SENDER,
        _vid("vertex_id", "the vertex, 0..4094 (Table I id)"),
        _dm("x_dm", "x in the sender's own odometry frame"),
        _dm("y_dm", "y in the sender's own odometry frame"),
        Field("prev_owner", 8, unit="id", doc="robot of the other end of the Algorithm 1 line-17 edge (last_vertex)"),
        _vid("prev_id", "last_vertex's id; 4095: no edge (the sender's first vertex)", none_ok=True),
        Field("ud_sectors", 32, unit="16 x 2 bit", doc="unexplored directions L: sector k (k * 22.5 deg, sender's "
              "frame) in bits 2k..2k+1: 0 none, 1 <= 3 m, 2 3-6 m, 3 > 6 m"),
        Field("desc_mean", 5, unit="code", doc="mean log range, (m - ln 0.2) / (ln 10 - ln 0.2) * 31"),
        Field("desc_std", 3, unit="code", doc="std of the log-range bins, clip(s, 0, 1.4) / 1.4 * 7"),
        *(Field(f"desc_{i}", 32, unit="8 x 4 bit", doc=f"z-scored log-range bins {8 * i}..{8 * i + 7} "
                f"(bin b: bearings [b, b+1) * 11.25 deg of the sender's frame), bin {8 * i} most significant")
          for i in range(_DESC_WORDS)),
    ),
    doc="A topological vertex, MR-TopoMap Table I (robot, id, position, descriptor, unexplored directions) "
        "with its Algorithm 1 line-17 edge (Table II), in the sender's own frame (240 bits).",
)

MREDGE = RecordType(
    2, "mredge", 6,
    (
        SENDER,
        Field("n1", 8, unit="id", doc="robot of vertex 1"), _vid("id1", "vertex 1"),
        Field("n2", 8, unit="id", doc="robot of vertex 2"), _vid("id2", "vertex 2"),
    ),
    doc="A topological edge, Table II: Algorithm 1 line-22 re-entry edges (line-17 edges ride in mrvtx).",
)

MRUD = RecordType(
    3, "mrud", 6,
    (
        SENDER,
        Field("owner_id", 8, unit="id", doc="robot that built the vertex"),
        _vid("vertex_id", "the vertex"),
        Field("clear_mask", 16, unit="bits", doc="sectors now explored or taken: bit k = sector k (III-E); "
              "receivers clear them (AND-NOT: idempotent, commutative)"),
    ),
    doc="Unexplored directions of a vertex that are explored now (the code's UnexploredDirectionsMsg, A13).",
)

MRLINK = RecordType(
    4, "mrlink", 9,
    (
        SENDER,
        Field("peer_id", 8, unit="id", doc="the teammate whose frame the transform maps from"),
        _dm("dx_dm", "translation of T_sender<-peer, x"),
        _dm("dy_dm", "translation of T_sender<-peer, y"),
        Field("dyaw", 12, unit="360/4096 deg", doc="rotation of T_sender<-peer, counter-clockwise, 0..360 deg"),
        Field("support", 6, unit="pairs", doc="consensus behind it, saturating at 63"),
    ),
    doc="The sender's current merge T_sender<-peer (optional, not in the paper): transitive merges and "
        "the inverse-consistency check.",
)

DIALECT = Dialect(DIALECT_ID, "mr_topomap", (MRVTX, MREDGE, MRUD, MRLINK))

assert (MRVTX.size_bytes, MREDGE.size_bytes, MRUD.size_bytes, MRLINK.size_bytes) == (30, 6, 6, 9)
assert MRVTX.bits_used == 240 and MRVTX.size_bytes <= 32        # issue 25: a vertex record <= 32 B
assert MRUD.padding_bits == 4 and MRLINK.padding_bits == 6


# ---- typed values ------------------------------------------------------------------------

class Vertex(NamedTuple):
    """One mrvtx as numbers: positions in dm of the owner's frame, the 32 descriptor codes."""

    owner: int
    vid: int
    x_dm: int
    y_dm: int
    prev_owner: int
    prev_id: int            # NO_VERTEX: no line-17 edge
    ud_sectors: int         # 16 x 2 bit, sector k in bits 2k..2k+1
    desc: Descriptor

    @property
    def key(self) -> tuple[int, int]:
        return self.owner, self.vid

    @property
    def x_m(self) -> float:
        return self.x_dm / 10.0

    @property
    def y_m(self) -> float:
        return self.y_dm / 10.0


class Edge(NamedTuple):
    sender: int
    n1: int
    id1: int
    n2: int
    id2: int


class UdClear(NamedTuple):
    sender: int
    owner: int
    vid: int
    clear_mask: int


class Link(NamedTuple):
    sender: int
    peer: int
    dx_dm: int
    dy_dm: int
    dyaw: int               # code, DYAW_CODES per turn
    support: int

    @property
    def yaw_rad(self) -> float:
        return self.dyaw * 2.0 * math.pi / DYAW_CODES


def sector_class(ud_sectors: int, k: int) -> int:
    """Distance class 0..3 of sector k."""
    return (ud_sectors >> (2 * k)) & 3


def sector_mask(ud_sectors: int) -> int:
    """The 16-bit mask of the sectors that hold an unexplored direction."""
    return sum(1 << k for k in range(SECTORS) if (ud_sectors >> (2 * k)) & 3)


def clear_sectors(ud_sectors: int, clear_mask: int) -> int:
    """ud_sectors with the sectors of clear_mask set to 0 (none)."""
    keep = 0
    for k in range(SECTORS):
        if not (clear_mask >> k) & 1:
            keep |= 3 << (2 * k)
    return ud_sectors & keep


def pack_sectors(classes) -> int:
    """16 distance classes (0..3) -> the 32-bit ud_sectors word."""
    classes = list(classes)
    assert len(classes) == SECTORS and all(0 <= int(c) <= 3 for c in classes)
    return sum(int(c) << (2 * k) for k, c in enumerate(classes))


def vertex_values(v: Vertex) -> dict[str, int]:
    codes = v.desc.codes
    assert len(codes) == BINS and all(0 <= c <= 15 for c in codes), "descriptor codes must be 32 values 0..15"
    out = {"sender_id": v.owner, "vertex_id": v.vid, "x_dm": v.x_dm, "y_dm": v.y_dm, "prev_owner": v.prev_owner,
           "prev_id": v.prev_id, "ud_sectors": v.ud_sectors, "desc_mean": v.desc.mean_code, "desc_std": v.desc.std_code}
    for i in range(_DESC_WORDS):
        word = 0
        for c in codes[CODES_PER_WORD * i:CODES_PER_WORD * (i + 1)]:
            word = (word << 4) | int(c)
        out[f"desc_{i}"] = word
    return out


def vertex_from_values(d) -> Vertex:
    codes = []
    for i in range(_DESC_WORDS):
        word = d[f"desc_{i}"]
        codes.extend((word >> (4 * (CODES_PER_WORD - 1 - j))) & 15 for j in range(CODES_PER_WORD))
    return Vertex(d["sender_id"], d["vertex_id"], d["x_dm"], d["y_dm"], d["prev_owner"], d["prev_id"],
                  d["ud_sectors"], Descriptor(tuple(codes), d["desc_mean"], d["desc_std"]))


def edge_values(e: Edge) -> dict[str, int]:
    return {"sender_id": e.sender, "n1": e.n1, "id1": e.id1, "n2": e.n2, "id2": e.id2}


def ud_values(u: UdClear) -> dict[str, int]:
    return {"sender_id": u.sender, "owner_id": u.owner, "vertex_id": u.vid, "clear_mask": u.clear_mask}


def link_values(lk: Link) -> dict[str, int]:
    return {"sender_id": lk.sender, "peer_id": lk.peer, "dx_dm": lk.dx_dm, "dy_dm": lk.dy_dm, "dyaw": lk.dyaw,
            "support": lk.support}


def encode_vertex(v: Vertex) -> bytes:
    """30 bytes; ValueError naming the field if a value is out of range (our own data)."""
    return codec.encode(MRVTX, vertex_values(v))


def encode_edge(e: Edge) -> bytes:
    return codec.encode(MREDGE, edge_values(e))


def encode_ud(u: UdClear) -> bytes:
    return codec.encode(MRUD, ud_values(u))


def encode_link(lk: Link) -> bytes:
    return codec.encode(MRLINK, link_values(lk))


class Decoded(NamedTuple):
    value: Vertex | Edge | UdClear | Link | None     # None: refused
    reason: Reason
    detail: str = ""


def _decode(rt: RecordType, data, make) -> Decoded:
    if not isinstance(data, (bytes, bytearray, memoryview)):
        return Decoded(None, Reason.BAD_LENGTH, f"{rt.name}: expected bytes, got {type(data).__name__}")
    d = codec.decode(rt, bytes(data))
    if d.values is None:
        return Decoded(None, d.reason, d.detail)
    return Decoded(make(d.values), Reason.OK)


def decode_vertex(data: bytes) -> Decoded:
    return _decode(MRVTX, data, vertex_from_values)


def decode_edge(data: bytes) -> Decoded:
    return _decode(MREDGE, data, lambda d: Edge(d["sender_id"], d["n1"], d["id1"], d["n2"], d["id2"]))


def decode_ud(data: bytes) -> Decoded:
    return _decode(MRUD, data, lambda d: UdClear(d["sender_id"], d["owner_id"], d["vertex_id"], d["clear_mask"]))


def decode_link(data: bytes) -> Decoded:
    return _decode(MRLINK, data, lambda d: Link(d["sender_id"], d["peer_id"], d["dx_dm"], d["dy_dm"], d["dyaw"],
                                                 d["support"]))


DECODERS = {"mrvtx": decode_vertex, "mredge": decode_edge, "mrud": decode_ud, "mrlink": decode_link}

assert MEAN_CODES == 1 << 5 and STD_CODES == 1 << 3       # desc_mean, desc_std widths

"""Meier et al.'s dialect: polygon vertices, which ids are alive, and target points on the
air (meier.md 5.2). Dialect id 2.

`poly` is the state of one vertex of the sender's polygon map at the sender's record counter
(replica.PolyRecord); `poly_gone` is the same for a vertex removed, without what a removed
vertex no longer has (a place, an edge): 8 bytes instead of 12, and vertices go about as
often as they come; `poly_alive` says which ids of a block of 64 are alive at a stamp
(replica.AliveRecord); `poly_nack` names frames of a teammate this robot lost, which the
teammate answers by sending the polygon records they carried again; `poly_sum` summarises
what a receiver of every record holds of one block of the sender's vertex ids, and
`poly_ask` asks for a block whose summary differs from the asker's copy (what a lost frame
request cannot name: frames lost in a spell out of range longer than the link's window, a
request lost, the last frame before the sender fell silent); `target` is the paper's
target point transmission (TPT): where the sender is heading, or that it released its
target, with a 7-bit sequence number so that an older one never overrides a newer.
"""
from __future__ import annotations

from collections.abc import Mapping

from firmware.comms.frame import SEQ_MODULUS
from firmware.comms.schema import SENDER, Dialect, Field, RecordType, position_cm
from firmware.schemes.meier.replica import (ALIVE_BLOCK_IDS, MAX_VERTEX_ID, STAMP_BITS, SUM_DIGEST_BITS, SUM_PART_IDS,
                                            SUM_PARTS, AliveRecord, PolyRecord)

DIALECT_ID = 2

# Lattice units on the air: a vertex sits on a corner of the coarse raster (meier.md A9).
LATTICE_M = 0.2
LATTICE_BITS = 15
TARGET_SEQ_BITS = 7

_STAMP = Field("stamp", STAMP_BITS, unit="records", doc="sender's polygon record counter (RFC 1982 order)")
# Which vertex a record is about and its neighbours in its ring (joined, if it was removed).
_VERTEX = (
    Field("vertex_id", 12, unit="id", lo=1, hi=MAX_VERTEX_ID, doc="the vertex"),
    Field("pred_id", 12, unit="id", hi=MAX_VERTEX_ID, doc="its predecessor in its ring"),
    Field("succ_id", 12, unit="id", hi=MAX_VERTEX_ID, doc="its successor in its ring"),
)
_KIND = Field("kind", 3, unit="enum", hi=4, doc="why it was sent: 0 refresh, 1 edge split, 2 vanished, "
              "3 broken boundary, 4 emerged (accounting only)")

POLY = RecordType(
    1, "poly", 12,
    (
        SENDER, _STAMP, *_VERTEX,
        Field("x_lat", LATTICE_BITS, True, "0.2 m", doc="x on the lattice of the shared frame"),
        Field("y_lat", LATTICE_BITS, True, "0.2 m", doc="y on the lattice of the shared frame"),
        Field("edge_type", 2, unit="enum", hi=1, doc="edge to the successor: 0 frontier, 1 wall"),
        Field("alive", 1, unit="bool", doc="0: removed, its predecessor and successor are joined (the "
              "sender says that with poly_gone)"),
        _KIND,
    ),
    doc="One vertex of the sender's polygon map at a stamp (Meier et al. ES / B / VP / EP packets).",
)

POLY_GONE = RecordType(
    4, "poly_gone", 8,
    (SENDER, _STAMP, *_VERTEX, _KIND),
    doc="A vertex of the sender's polygon map removed at a stamp, its predecessor and successor now "
        "joined (Meier et al. VP packet): a poly tombstone without a place.",
)

NACK_MORE_BITS = 16

POLY_NACK = RecordType(
    5, "poly_nack", 6,
    (
        SENDER,
        Field("of_id", 8, unit="id", doc="the teammate whose frames the sender lost"),
        Field("first_seq", 16, unit="frames", doc="the first frame lost (the link's sequence number)"),
        Field("more", NACK_MORE_BITS, unit="bits", doc="bit k: frame first_seq + 1 + k lost too"),
    ),
    doc="Frames of a teammate this robot lost: the teammate sends the polygon records they carried again "
        "(meier.md 5.4's poly_nack, by frame).",
)

_BLOCK = Field("block", 6, unit="64 ids", doc="vertex ids 64 block .. 64 block + 63")

POLY_SUM = RecordType(
    6, "poly_sum", 16,
    (SENDER, _BLOCK,
     Field("upto", STAMP_BITS, unit="records", doc="the sender's record counter when it summarised: the summary "
                                                    "covers every record stamped before"),
     *(Field(f"part{k}", SUM_DIGEST_BITS, unit="crc32 bits",
             doc=f"of the id and stamp of the newest record of each vertex of ids 64 block + {SUM_PART_IDS * k} .. "
                 f"{SUM_PART_IDS * (k + 1) - 1} the sender made (the low {SUM_DIGEST_BITS} bits)")
       for k in range(SUM_PARTS))),
    doc="What a receiver of every polygon record of the sender holds of one block of its vertex ids, part by part; "
        "a receiver whose copy differs, and holds nothing of the block stamped since, asks for the parts that "
        "differ with poly_ask.",
)

POLY_ASK = RecordType(
    7, "poly_ask", 4,
    (SENDER, Field("of_id", 8, unit="id", doc="the teammate asked"), _BLOCK,
     Field("parts", SUM_PARTS, unit="bits", doc=f"bit k: ids 64 block + {SUM_PART_IDS} k .. + {SUM_PART_IDS - 1}")),
    doc="The sender's copy of some parts of a block of the teammate's polygon map differs from the teammate's "
        "poly_sum: the teammate sends the newest record of each vertex of those parts again.",
)

POLY_ALIVE = RecordType(
    2, "poly_alive", 12,
    (
        SENDER, _STAMP, _BLOCK,
        Field("alive_lo", 32, unit="bits", doc="which ids 64 block + 0..31 are alive"),
        Field("alive_hi", 32, unit="bits", doc="which ids 64 block + 32..63 are alive"),
    ),
    doc="Which vertex ids of a block are alive at a stamp: a refresh for receivers that lost records.",
)

TARGET = RecordType(
    3, "target", 8,
    (
        SENDER, position_cm("x"), position_cm("y"),
        Field("claimed", 1, unit="bool", doc="1: heading there; 0: the sender released its target"),
        Field("target_seq", TARGET_SEQ_BITS, unit="targets", doc="sender's target counter (RFC 1982 order)"),
    ),
    doc="Target point transmission (TPT): where the sender is heading (Meier et al. Algorithm 1 line 8).",
)

DIALECT = Dialect(DIALECT_ID, "meier", (POLY, POLY_ALIVE, TARGET, POLY_GONE, POLY_NACK, POLY_SUM, POLY_ASK))

assert POLY.bits_used == 96 and POLY_GONE.bits_used == 63 and POLY_ALIVE.bits_used == 94
assert (1 << 6) * ALIVE_BLOCK_IDS > MAX_VERTEX_ID


def poly_values(r: PolyRecord) -> tuple[str, dict[str, int]]:
    """The record type and field values that say r: a tombstone goes as the shorter poly_gone."""
    if not r.alive:
        return "poly_gone", {"sender_id": r.sender_id, "stamp": r.stamp, "vertex_id": r.vertex_id,
                             "pred_id": r.pred_id, "succ_id": r.succ_id, "kind": r.kind}
    return "poly", {"sender_id": r.sender_id, "stamp": r.stamp, "vertex_id": r.vertex_id, "pred_id": r.pred_id,
            "succ_id": r.succ_id, "x_lat": r.x_lat, "y_lat": r.y_lat, "edge_type": r.edge_type,
            "alive": int(r.alive), "kind": r.kind}


def poly_record(rtype: str, v: Mapping[str, int]) -> PolyRecord:
    """The PolyRecord a poly or poly_gone record says (a tombstone's place reads 0, 0)."""
    if rtype == "poly_gone":
        return PolyRecord(v["sender_id"], v["stamp"], v["vertex_id"], v["pred_id"], v["succ_id"], 0, 0, 0, False,
                          v["kind"])
    return PolyRecord(v["sender_id"], v["stamp"], v["vertex_id"], v["pred_id"], v["succ_id"], v["x_lat"],
                      v["y_lat"], v["edge_type"], bool(v["alive"]), v["kind"])


def alive_values(r: AliveRecord) -> dict[str, int]:
    return {"sender_id": r.sender_id, "stamp": r.stamp, "block": r.block,
            "alive_lo": r.alive_bits & 0xFFFFFFFF, "alive_hi": r.alive_bits >> 32}


def alive_record(v: Mapping[str, int]) -> AliveRecord:
    return AliveRecord(v["sender_id"], v["stamp"], v["block"], v["alive_lo"] | v["alive_hi"] << 32)


def nack_values(sender_id: int, of_id: int, seqs: list[int]) -> list[dict[str, int]]:
    """poly_nack records that name these frame sequence numbers (oldest first, as few as
    the `more` bits allow)."""
    out: list[dict[str, int]] = []
    for seq in seqs:
        if out:
            k = (seq - out[-1]["first_seq"]) % SEQ_MODULUS - 1
            if 0 <= k < NACK_MORE_BITS:
                out[-1]["more"] |= 1 << k
                continue
        out.append({"sender_id": sender_id, "of_id": of_id, "first_seq": seq, "more": 0})
    return out


def nack_seqs(v: Mapping[str, int]) -> list[int]:
    """The frame sequence numbers a poly_nack record names."""
    return [v["first_seq"]] + [(v["first_seq"] + 1 + k) % SEQ_MODULUS
                               for k in range(NACK_MORE_BITS) if v["more"] >> k & 1]

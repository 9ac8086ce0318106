"""Pereira et al.'s records on the air (pereira.md 5.4): place, gate, claim, intent, summary.

Dialect id 3 (Bayer & Faigl 1, Meier 2). The spec numbered the records 4..8 when every
record type lived in one table; with one dialect per scheme they are codes 1..5 of this
dialect, same fields, same sizes (9, 9, 10, 12, 16 bytes). The scheme (scheme.py) is
registered, so `firmware.schemes.all_dialects()` holds this dialect and every node decodes
it; `encode`/`decode` here take the RecordType objects directly, without the registry.

`place`, `gate` and `claim` share the origin's one 16-bit record counter `oseq` (the
paper's timestamp, compared per origin only, RFC 1982); they are the grow-only record set
every robot folds into the same region graph (regions.py) and statuses (status.py).
`intent` and `summary` are ephemeral (Algorithm 1 and anti-entropy), not part of the set.

Positions are decimetres in the shared mission frame, 16-bit signed (+-3276.7 m).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import NamedTuple

from firmware.comms import codec
from firmware.comms.codec import Reason, RecordDecode
from firmware.comms.schema import SENDER, Dialect, Field, RecordType

DIALECT_ID = 3

OSEQ_BITS = 16
EMPTY_ORIGIN = 255           # a summary slot holding no origin
ORACLE_ORIGIN = 254          # records preloaded from the ground truth (pereira-oracle, later)
DIR_CODES = 256              # gate direction: theta = code * pi / 256, modulo pi
HALF_UNIT_M = 0.02           # half_2cm: one count is 2 cm
GOAL_DIST_MAX_DM = (1 << 12) - 1

INTENT_STATES = ("idle", "exploring", "done", "returning")
CATEGORIES = ("fu", "c", "fs", "o")   # following-unexplored, current, following-semi-explored, others


def _dm(name: str, doc: str) -> Field:
    return Field(name, 16, True, "dm", doc=doc)


_OSEQ = Field("oseq", OSEQ_BITS, unit="records", doc="origin's record counter (RFC 1982 order); the paper's timestamp")

PLACE = RecordType(
    1, "place", 9,
    (
        SENDER, _OSEQ,
        _dm("x_dm", "x of the place in the shared frame"),
        _dm("y_dm", "y of the place in the shared frame"),
        Field("clear_dm", 8, unit="dm", doc="radius of the disc certified FREE in the sender's map, saturating"),
        Field("link_back", 4, unit="records", doc="oseq gap to the sender's previous place (0: none)"),
    ),
    doc="A place the sender drove through, every d_place of travel, with a certified free radius.",
)

GATE = RecordType(
    2, "gate", 9,
    (
        SENDER, _OSEQ,
        _dm("x_dm", "x of the gate centre"),
        _dm("y_dm", "y of the gate centre"),
        Field("dir_code", 8, unit="pi/256 rad", doc="direction jamb a -> b, modulo pi"),
        Field("half_2cm", 8, unit="2 cm", doc="half the distance between the jambs (<= 5.1 m)"),
    ),
    doc="A narrowing (doorway, corridor mouth) the sender saw whole and confirmed.",
)

CLAIM = RecordType(
    3, "claim", 10,
    (
        Field("sender_id", 8, unit="id", doc="origin of the claim (relays forward it unchanged)"),
        _OSEQ,
        _dm("anchor_x_dm", "x of the region's anchor in the origin's view"),
        _dm("anchor_y_dm", "y of the region's anchor in the origin's view"),
        Field("sig", 16, unit="crc16",
              doc="the region's signature in the origin's view (CRC of its gate and place keys)"),
        Field("explored", 1, unit="bool", doc="the origin judges the region explored (0: retracted)"),
        Field("virtual", 1, unit="bool", doc="the region was a virtual one (behind a gate) for the origin"),
    ),
    doc="A region's exploration status by one origin (Pereira eq. 1 as a per-origin register).",
)

INTENT = RecordType(
    4, "intent", 12,
    (
        SENDER,
        _dm("x_dm", "sender's position p^r"),
        _dm("y_dm", "sender's position p^r"),
        _dm("goal_x_dm", "sender's goal p^g"),
        _dm("goal_y_dm", "sender's goal p^g"),
        Field("goal_dist_dm", 12, unit="dm", doc="eq. 3 distance to the goal, saturating at 409.5 m"),
        Field("state", 2, unit="enum", doc="0 idle, 1 exploring, 2 done, 3 returning"),
        Field("category", 2, unit="enum", doc="category of the goal: 0 fu, 1 c, 2 fs, 3 o"),
        Field("iseq", 8, unit="intents", doc="sender's intent counter (RFC 1982 order)"),
    ),
    doc="Where the sender is and where it is headed (h_m, p^r_m, p^g_m of the paper's message).",
)

SUMMARY_SLOTS = 5
SUMMARY = RecordType(
    5, "summary", 16,
    (SENDER,) + tuple(
        f for k in range(SUMMARY_SLOTS) for f in (
            Field(f"origin{k}", 8, unit="id", doc=f"slot {k}: an origin ({EMPTY_ORIGIN}: empty slot)"),
            Field(f"upto{k}", OSEQ_BITS, unit="records", doc=f"slot {k}: highest contiguous oseq held of it"),
        )),
    doc="Anti-entropy: which records the sender holds, per origin (up to five origins a record).",
)

RECORDS = (PLACE, GATE, CLAIM, INTENT, SUMMARY)
DIALECT = Dialect(DIALECT_ID, "pereira", RECORDS)

SIZES_BYTES = {"place": 9, "gate": 9, "claim": 10, "intent": 12, "summary": 16}
assert {r.name: r.size_bytes for r in RECORDS} == SIZES_BYTES
assert [r.bits_used for r in RECORDS] == [68, 72, 74, 96, 128]
_BY_NAME = {r.name: r for r in RECORDS}


# ---- typed records ---------------------------------------------------------------------

class Place(NamedTuple):
    sender_id: int
    oseq: int
    x_dm: int
    y_dm: int
    clear_dm: int
    link_back: int


class Gate(NamedTuple):
    sender_id: int
    oseq: int
    x_dm: int
    y_dm: int
    dir_code: int
    half_2cm: int


class Claim(NamedTuple):
    sender_id: int        # the origin
    oseq: int
    anchor_x_dm: int
    anchor_y_dm: int
    sig: int
    explored: int
    virtual: int


class Intent(NamedTuple):
    sender_id: int
    x_dm: int
    y_dm: int
    goal_x_dm: int
    goal_y_dm: int
    goal_dist_dm: int
    state: int
    category: int
    iseq: int


class Summary(NamedTuple):
    sender_id: int
    entries: tuple[tuple[int, int], ...]   # (origin, highest contiguous oseq held), at most five, no empty slots


_TYPED = {"place": Place, "gate": Gate, "claim": Claim, "intent": Intent}


def values_of(record: Place | Gate | Claim | Intent | Summary) -> dict[str, int]:
    """A typed record as the codec's field values."""
    if isinstance(record, Summary):
        if len(record.entries) > SUMMARY_SLOTS:
            raise ValueError(f"summary: {len(record.entries)} entries, at most {SUMMARY_SLOTS}")
        slots = list(record.entries) + [(EMPTY_ORIGIN, 0)] * (SUMMARY_SLOTS - len(record.entries))
        out = {"sender_id": record.sender_id}
        for k, (origin, upto) in enumerate(slots):
            if k < len(record.entries) and origin == EMPTY_ORIGIN:
                raise ValueError(f"summary: origin {EMPTY_ORIGIN} marks an empty slot")
            out[f"origin{k}"], out[f"upto{k}"] = origin, upto
        return out
    return {k: int(v) for k, v in record._asdict().items()}


def typed(name: str, values: Mapping[str, int]) -> Place | Gate | Claim | Intent | Summary:
    """Field values (as decode gives them) as the typed record."""
    if name == "summary":
        entries = tuple((values[f"origin{k}"], values[f"upto{k}"]) for k in range(SUMMARY_SLOTS)
                        if values[f"origin{k}"] != EMPTY_ORIGIN)
        return Summary(values["sender_id"], entries)
    return _TYPED[name](**{f: values[f] for f in _TYPED[name]._fields})


def record_name(record: object) -> str:
    for name, cls in (*_TYPED.items(), ("summary", Summary)):
        if isinstance(record, cls):
            return name
    raise TypeError(f"not a Pereira record: {type(record).__name__}")


def encode(record: Place | Gate | Claim | Intent | Summary) -> bytes:
    """A typed record as its fixed-size bytes; ValueError if a value is out of its field's range."""
    return codec.encode(_BY_NAME[record_name(record)], values_of(record))


class Decoded(NamedTuple):
    record: Place | Gate | Claim | Intent | Summary | None
    reason: Reason
    detail: str = ""


def decode(name: str, data: bytes) -> Decoded:
    """Bytes of one record of type `name` -> the typed record, or None and why. Never raises
    for any bytes (an unknown name is a programming error: ValueError)."""
    rt = _BY_NAME.get(name)
    if rt is None:
        raise ValueError(f"unknown Pereira record {name!r}; known: {', '.join(_BY_NAME)}")
    got: RecordDecode = codec.decode(rt, bytes(data))
    if got.values is None:
        return Decoded(None, got.reason, got.detail)
    if name == "summary":
        # An empty slot carries nothing: its counter must read zero, so one summary has one
        # encoding, and a slot is empty or not.
        for k in range(SUMMARY_SLOTS):
            if got.values[f"origin{k}"] == EMPTY_ORIGIN and got.values[f"upto{k}"] != 0:
                return Decoded(None, Reason.OUT_OF_RANGE, f"summary: empty slot {k} with upto {got.values[f'upto{k}']}")
    return Decoded(typed(name, got.values), Reason.OK)


# ---- wire units --------------------------------------------------------------------------

def dm(v_m: float) -> int:
    """Metres to the wire's decimetres, saturating at the 16-bit range."""
    return max(-(1 << 15), min((1 << 15) - 1, int(round(v_m * 10.0))))


def dir_code_of(theta_rad: float) -> int:
    """A direction modulo pi as dir_code (nearest step of pi/256)."""
    return int(round((theta_rad % math.pi) / (math.pi / DIR_CODES))) % DIR_CODES


def half_2cm_of(half_m: float) -> int:
    """Half a jamb distance as half_2cm, saturating at 255 (5.1 m)."""
    return max(0, min(255, int(round(half_m / HALF_UNIT_M))))


def serial_newer(a: int, b: int, bits: int = OSEQ_BITS) -> bool:
    """RFC 1982: is a newer than b? (Undefined at exactly half the space apart: False.)"""
    d = (a - b) % (1 << bits)
    return 0 < d < (1 << (bits - 1))

"""The one declarative table of radio record types (the pymavlink / PX4 msg pattern).

Everything about a record on the air comes from `RECORD_TYPES`: its bit layout, its fixed
size, its range checks, the schema fingerprint folded into every frame CRC, the generated
frozen dataclasses, the Markdown documentation and the Wireshark dissector. Adding a record
type is adding one `RecordType(...)` row below; its size is checked at import.

Wire layout of a record: the fields in table order, most significant bit first, packed
without gaps into a big-endian integer, then zero padding up to the next byte boundary
(the padding must read back as zero). A record carries no type byte: the frame's group tag
says which type a run of records has (see frame.py), so a Bayer & Faigl Table I vertex
costs exactly 12 bytes on the air.

Values on the wire are integers in fixed-point units named in the field (x_cm, yaw_cdeg).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import crcmod.predefined

# Frame format version; part of the fingerprint, so a change here changes every CRC.
FRAME_VERSION = 1

# The frame CRC, by its catalogue name (crcmod "modbus" = reveng CRC-16/MODBUS: poly 0x8005
# reflected, init 0xFFFF, xorout 0; check 0x4B37 over b"123456789").
# Why not CRC-16/DNP (0x3D65)? Its polynomial has period 151 bits: its Hamming distance 6
# holds only up to 135 data bits, and two flipped bits 151 apart pass it. Our frames run to
# 255 bytes (2040 bits). 0x8005 = (x + 1)(x^15 + x + 1) has period 32767, so every 1-, 2- and
# odd-bit error in any frame is caught (HD 4, the best a 16-bit CRC reaches at this length),
# and it differs from the LoRa PHY's CRC-16/CCITT (0x1021), so the two checks are independent.
CRC_NAME = "modbus"
CRC_CATALOGUE_NAME = "CRC-16/MODBUS"
CRC_CHECK = 0x4B37
crc16 = crcmod.predefined.mkPredefinedCrcFun(CRC_NAME)
assert crc16(b"123456789") == CRC_CHECK, "crcmod catalogue entry does not match its check value"

TYPE_CODE_BITS = 4          # a record type code travels in the high nibble of a group tag
MAX_TYPE_CODE = (1 << TYPE_CODE_BITS) - 1


@dataclass(frozen=True)
class Field:
    """One fixed-point field. `lo`/`hi` bound the valid integer values on the wire
    (inclusive); None means the full range that `bits` can hold."""

    name: str             # carries its unit: x_cm, yaw_cdeg
    bits: int
    signed: bool = False
    unit: str = ""        # meaning of one count, for humans and the dissector
    lo: int | None = None
    hi: int | None = None
    doc: str = ""

    @property
    def raw_min(self) -> int:
        return -(1 << (self.bits - 1)) if self.signed else 0

    @property
    def raw_max(self) -> int:
        return (1 << (self.bits - 1)) - 1 if self.signed else (1 << self.bits) - 1

    @property
    def min_value(self) -> int:
        return self.raw_min if self.lo is None else self.lo

    @property
    def max_value(self) -> int:
        return self.raw_max if self.hi is None else self.hi


@dataclass(frozen=True)
class RecordType:
    code: int             # 1..15, unique; 0 is never a valid code so zeroed bytes are rejected
    name: str
    size_bytes: int       # declared size; must equal the packed size (checked at import)
    fields: tuple[Field, ...]
    doc: str = ""

    @property
    def bits_used(self) -> int:
        return sum(f.bits for f in self.fields)

    @property
    def padding_bits(self) -> int:
        return 8 * self.size_bytes - self.bits_used

    def field_offsets(self) -> tuple[tuple[Field, int], ...]:
        """(field, bit offset from the record's most significant bit) in wire order."""
        out, off = [], 0
        for f in self.fields:
            out.append((f, off))
            off += f.bits
        return tuple(out)


def _pos(axis: str) -> Field:
    return Field(f"{axis}_cm", 24, True, "cm", doc=f"{axis} in the shared mission frame")


SENDER = Field("sender_id", 8, unit="id", doc="robot that produced the record")

# e_inf (Bayer & Faigl eq. 3, an entropy in bits) spans four orders of magnitude, so it is
# sent on a saturating logarithmic scale: code = min(255, round(16 * log2(1 + e_inf_bit))).
# 16 codes per octave = 4.4 % steps; code 255 means >= 62 900 bit.
E_INF_CODES_PER_OCTAVE = 16


def e_inf_bit_to_code(e_inf_bit: float) -> int:
    if not e_inf_bit > 0.0:          # also maps NaN to 0
        return 0
    return min(255, round(E_INF_CODES_PER_OCTAVE * math.log2(1.0 + e_inf_bit)))


def e_inf_code_to_bit(code: int) -> float:
    return 2.0 ** (code / E_INF_CODES_PER_OCTAVE) - 1.0


E_INF = Field("e_inf_code", 8, unit="16*log2(1+bit), saturating",
              doc="expected information gain at the vertex, logarithmic code")

RECORD_TYPES: tuple[RecordType, ...] = (
    RecordType(
        1, "topo", 12,
        (
            SENDER, _pos("x"), _pos("y"), _pos("z"),
            Field("presence", 1, unit="bool", doc="sender was at p (Table I 'presence of ID at p')"),
            E_INF,
            Field("info_version", 7, unit="revisions", doc="how often the sender revised e_inf at this vertex, "
                  "saturating at 127; the sender's highest revision counts"),
        ),
        doc="Topological map vertex, Bayer & Faigl Table I (8+72+1+8 = 89 bits), plus a 7-bit revision in "
            "what was padding so e_inf can rise again without a clock (12 B).",
    ),
    RecordType(
        2, "pose", 12,
        (
            SENDER, _pos("x"), _pos("y"),
            Field("yaw_cdeg", 16, True, "0.01 deg", -18000, 18000, "heading, counter-clockwise from +x"),
            Field("speed_cmps", 8, unit="cm/s", doc="forward speed, saturating at 255"),
            Field("exploring", 1, unit="bool", doc="has an exploration target"),
            Field("done", 1, unit="bool", doc="sees no frontier left; finished"),
            Field("returning", 1, unit="bool", doc="driving back to the start"),
            Field("vertex_count", 12, unit="vertices", doc="vertices in the sender's topological map, saturating"),
        ),
        doc="Heartbeat: where the sender is and what it is doing.",
    ),
    RecordType(
        3, "target", 11,
        (
            SENDER, _pos("x"), _pos("y"),
            Field("path_cost_dm", 16, unit="dm", doc="sender's planned path length to the target, saturating"),
            Field("claimed", 1, unit="bool", doc="1 = sender claims the target, 0 = releases it"),
            E_INF,
        ),
        doc="Target announcement: the goal the sender is heading for and what reaching it costs.",
    ),
)

BY_NAME: dict[str, RecordType] = {r.name: r for r in RECORD_TYPES}
BY_CODE: dict[int, RecordType] = {r.code: r for r in RECORD_TYPES}


def check_table(types: tuple[RecordType, ...]) -> None:
    """AssertionError naming the first inconsistency (run on RECORD_TYPES at import)."""
    assert len({r.name for r in types}) == len(types), "duplicate record type name"
    assert len({r.code for r in types}) == len(types), "duplicate record type code"
    for r in types:
        assert 1 <= r.code <= MAX_TYPE_CODE, f"{r.name}: code {r.code} outside 1..{MAX_TYPE_CODE}"
        assert r.name.isidentifier(), f"{r.name}: not an identifier"
        names = [f.name for f in r.fields]
        assert len(set(names)) == len(names), f"{r.name}: duplicate field name"
        assert r.size_bytes == math.ceil(r.bits_used / 8), (
            f"{r.name}: declared {r.size_bytes} B but the fields pack into {r.bits_used} bits "
            f"({math.ceil(r.bits_used / 8)} B)")
        for f in r.fields:
            assert f.name.isidentifier(), f"{r.name}.{f.name}: not an identifier"
            assert 1 <= f.bits <= 32, f"{r.name}.{f.name}: bits must be 1..32"
            assert not (f.signed and f.bits < 2), f"{r.name}.{f.name}: signed needs >= 2 bits"
            assert f.raw_min <= f.min_value <= f.max_value <= f.raw_max, (
                f"{r.name}.{f.name}: range [{f.min_value}, {f.max_value}] does not fit {f.bits} bits")


check_table(RECORD_TYPES)
assert BY_NAME["topo"].bits_used == 96 and BY_NAME["topo"].size_bytes == 12  # Table I + revision


def fingerprint(types: tuple[RecordType, ...] = RECORD_TYPES, version: int = FRAME_VERSION) -> int:
    """CRC-16 of everything that decides how bytes are read (pymavlink's CRC_EXTRA, for the
    whole table): version, codes, names, sizes, field names, widths, signs, units, ranges.
    Documentation strings are left out so rewording a doc keeps peers compatible."""
    parts = [f"lorascout-frame-v{version}"]
    for r in sorted(types, key=lambda r: r.code):
        parts.append(f"{r.code}:{r.name}:{r.size_bytes}")
        for f in r.fields:
            parts.append(f"{f.name}:{f.bits}:{'s' if f.signed else 'u'}:{f.unit}:{f.min_value}:{f.max_value}")
    return crc16(";".join(parts).encode("utf-8"))


SCHEMA_FINGERPRINT = fingerprint()


def _class_name(name: str) -> str:
    return "".join(p.capitalize() for p in name.split("_")) + "Record"


# One generated frozen dataclass per record type (TopoRecord, PoseRecord, ...), for code
# that prefers attribute access to dicts; the codec accepts either.
RECORD_CLASSES: dict[str, type] = {
    r.name: dataclasses.make_dataclass(
        _class_name(r.name), [(f.name, int) for f in r.fields], frozen=True,
        namespace={"__doc__": r.doc, "record_type": r.name},
    )
    for r in RECORD_TYPES
}


def record_type(name_or_type: str | RecordType) -> RecordType:
    if isinstance(name_or_type, RecordType):
        return name_or_type
    try:
        return BY_NAME[name_or_type]
    except KeyError:
        raise ValueError(f"unknown record type {name_or_type!r}; known: {', '.join(BY_NAME)}") from None


def markdown_table(types: tuple[RecordType, ...] = RECORD_TYPES) -> str:
    """Every record type as Markdown: for the README and `lorascout inspect --schema`."""
    lines = [f"Frame version {FRAME_VERSION}, {CRC_CATALOGUE_NAME} with schema fingerprint "
             f"0x{SCHEMA_FINGERPRINT:04X} folded in.", ""]
    for r in types:
        lines.append(f"### `{r.name}` (type {r.code}, {r.size_bytes} bytes: "
                     f"{r.bits_used} bits + {r.padding_bits} padding)")
        lines.append("")
        if r.doc:
            lines.extend([r.doc, ""])
        lines.append("| field | bits | signed | unit | valid range | meaning |")
        lines.append("|---|---:|:---:|---|---|---|")
        for f in r.fields:
            lines.append(f"| `{f.name}` | {f.bits} | {'yes' if f.signed else 'no'} | {f.unit} "
                         f"| {f.min_value} .. {f.max_value} | {f.doc} |")
        lines.append("")
    return "\n".join(lines)

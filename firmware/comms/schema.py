"""Record dialects: the declarative record tables (the pymavlink common + dialect pattern).

A `Dialect` is one table of record types with an id (0..255, travels in every frame header),
a name and a fingerprint. The core dialect `CORE` (id 0) holds what every scheme sends (the
heartbeat `pose`); each scheme owns one dialect of its own, defined in its package
(firmware/schemes/<scheme>/records.py), and the registry assembles them
(firmware.schemes.all_dialects() -> a `DialectSet`). Record codes (1..15) are unique within
a dialect; record names are unique across every dialect of a set, so code that names a
record ("topo", "pose") does not need to know its dialect.

Everything about a record on the air comes from its table row: its bit layout, its fixed
size, its range checks, the fingerprints folded into every frame CRC, the generated frozen
dataclasses, the Markdown documentation and the Wireshark dissector. Adding a record type is
adding one `RecordType(...)` row to its dialect; sizes are checked when the dialect is built.

Why one fingerprint per dialect and not one for everything: a frame's CRC folds in the core
fingerprint and the fingerprint of the frame's own dialect only (see frame.py), so changing
one scheme's table breaks only that scheme's frames; peers whose other dialects differ still
read them.

Wire layout of a record: the fields in table order, most significant bit first, packed
without gaps into a big-endian integer, then zero padding up to the next byte boundary
(the padding must read back as zero). A record carries no type byte: the frame's group tag
says which dialect and code a run of records has (see frame.py), so a Bayer & Faigl
Table I vertex costs exactly 12 bytes on the air.

Values on the wire are integers in fixed-point units named in the field (x_cm, yaw_cdeg).
"""
from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass

import crcmod.predefined

# Frame format version; part of every fingerprint, so a change here changes every CRC.
# Version 2: the dialect id in the header and the dialect bit in every group tag.
FRAME_VERSION = 2

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

# The frame's fixed parts, here because they bound what a record may be (frame.py uses them).
MAX_FRAME_BYTES = 255          # LoRa PHY payload limit (and the RN2483's `radio tx`)
FRAME_HEADER_BYTES = 7
FRAME_CRC_BYTES = 2
GROUP_TAG_BYTES = 1
# The largest record one frame can carry: alone, behind the header and its group tag.
MAX_RECORD_BYTES = MAX_FRAME_BYTES - FRAME_HEADER_BYTES - GROUP_TAG_BYTES - FRAME_CRC_BYTES

TYPE_CODE_BITS = 4          # a record code travels in bits 6..3 of a group tag
MAX_TYPE_CODE = (1 << TYPE_CODE_BITS) - 1
MAX_DIALECT_ID = 255        # one header byte
CORE_DIALECT_ID = 0
# Folded into the CRC in place of the frame dialect's fingerprint when the frame carries core
# records only (dialect id 0): the core fingerprint is folded in already.
NO_DIALECT_FINGERPRINT = 0x0000


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
    code: int             # 1..15, unique within its dialect; 0 is never valid so zeroed bytes are rejected
    name: str             # unique across every dialect of a DialectSet
    size_bytes: int       # declared size; must equal the packed size (checked with the dialect)
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

    @functools.cached_property
    def values_class(self) -> type:
        """A generated frozen dataclass (TopoRecord, PoseRecord, ...) for code that prefers
        attribute access to dicts; the codec accepts either."""
        return dataclasses.make_dataclass(
            "".join(p.capitalize() for p in self.name.split("_")) + "Record",
            [(f.name, int) for f in self.fields], frozen=True,
            namespace={"__doc__": self.doc, "record_type": self.name})


def check_table(types: tuple[RecordType, ...]) -> None:
    """AssertionError naming the first inconsistency in one dialect's table."""
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
        assert r.size_bytes <= MAX_RECORD_BYTES, (
            f"{r.name}: {r.size_bytes} B, one frame carries at most {MAX_RECORD_BYTES} B of one record")
        for f in r.fields:
            assert f.name.isidentifier(), f"{r.name}.{f.name}: not an identifier"
            assert 1 <= f.bits <= 32, f"{r.name}.{f.name}: bits must be 1..32"
            assert not (f.signed and f.bits < 2), f"{r.name}.{f.name}: signed needs >= 2 bits"
            assert f.raw_min <= f.min_value <= f.max_value <= f.raw_max, (
                f"{r.name}.{f.name}: range [{f.min_value}, {f.max_value}] does not fit {f.bits} bits")


def fingerprint(dialect_id: int, name: str, types: tuple[RecordType, ...], version: int = FRAME_VERSION) -> int:
    """CRC-16 of everything that decides how a dialect's bytes are read (pymavlink's
    CRC_EXTRA, for one message set): frame version, dialect id and name, codes, record names,
    sizes, field names, widths, signs, units, ranges. Documentation strings are left out so
    rewording a doc keeps peers compatible."""
    parts = [f"lorascout-frame-v{version}", f"dialect:{dialect_id}:{name}"]
    for r in sorted(types, key=lambda r: r.code):
        parts.append(f"{r.code}:{r.name}:{r.size_bytes}")
        for f in r.fields:
            parts.append(f"{f.name}:{f.bits}:{'s' if f.signed else 'u'}:{f.unit}:{f.min_value}:{f.max_value}")
    return crc16(";".join(parts).encode("utf-8"))


@dataclass(frozen=True)
class Dialect:
    """One record table with its id on the wire. Checked when built (AssertionError naming
    the first inconsistency)."""

    id: int               # 0 = the core dialect; a scheme's dialect 1..255
    name: str
    records: tuple[RecordType, ...]

    def __post_init__(self) -> None:
        assert isinstance(self.id, int) and 0 <= self.id <= MAX_DIALECT_ID, (
            f"dialect {self.name!r}: id {self.id!r} outside 0..{MAX_DIALECT_ID}")
        assert self.name.isidentifier(), f"dialect {self.name!r}: not an identifier"
        check_table(self.records)

    @functools.cached_property
    def fingerprint(self) -> int:
        return fingerprint(self.id, self.name, self.records)

    @functools.cached_property
    def by_code(self) -> dict[int, RecordType]:
        return {r.code: r for r in self.records}

    @functools.cached_property
    def by_name(self) -> dict[str, RecordType]:
        return {r.name: r for r in self.records}


class DialectSet:
    """The dialects a node knows: the core dialect (id 0) plus any number of others, with
    unique ids, unique dialect names and record names unique across all of them (checked
    here, AssertionError naming the clash)."""

    def __init__(self, dialects: Iterable[Dialect]) -> None:
        self._by_id: dict[int, Dialect] = {}
        self._by_dialect_name: dict[str, Dialect] = {}
        self._by_record: dict[str, tuple[Dialect, RecordType]] = {}
        for d in dialects:
            if self._by_id.get(d.id) == d:
                continue                  # the same dialect twice (two schemes sharing one)
            assert d.id not in self._by_id, f"dialect id {d.id} used by {self._by_id.get(d.id).name!r} and {d.name!r}"
            assert d.name not in self._by_dialect_name, f"two dialects named {d.name!r}"
            for r in d.records:
                other = self._by_record.get(r.name)
                assert other is None, f"record name {r.name!r} in dialects {other[0].name!r} and {d.name!r}"
                self._by_record[r.name] = (d, r)
            self._by_id[d.id] = d
            self._by_dialect_name[d.name] = d
        assert CORE_DIALECT_ID in self._by_id, "a dialect set needs the core dialect (id 0)"
        self._by_id = dict(sorted(self._by_id.items()))

    @property
    def core(self) -> Dialect:
        return self._by_id[CORE_DIALECT_ID]

    def __iter__(self) -> Iterator[Dialect]:
        return iter(self._by_id.values())

    def __len__(self) -> int:
        return len(self._by_id)

    def __contains__(self, dialect: object) -> bool:
        return isinstance(dialect, Dialect) and self._by_id.get(dialect.id) == dialect

    @property
    def by_id(self) -> Mapping[int, Dialect]:
        return dict(self._by_id)

    def get(self, dialect_id: int) -> Dialect | None:
        return self._by_id.get(dialect_id)

    def lookup(self, dialect_id: int, code: int) -> RecordType | None:
        """The record type with `code` in dialect `dialect_id`, or None."""
        d = self._by_id.get(dialect_id)
        return None if d is None else d.by_code.get(code)

    def record(self, name_or_type: str | RecordType) -> RecordType:
        """A record type by name (any dialect); ValueError listing the known names."""
        if isinstance(name_or_type, RecordType):
            return name_or_type
        try:
            return self._by_record[name_or_type][1]
        except (KeyError, TypeError):
            raise ValueError(f"unknown record type {name_or_type!r}; known: {', '.join(self._by_record)}") from None

    def dialect_of(self, name_or_type: str | RecordType) -> Dialect:
        """The dialect a record type belongs to; ValueError if none here holds it."""
        name = name_or_type.name if isinstance(name_or_type, RecordType) else name_or_type
        hit = self._by_record.get(name)
        if hit is None or (isinstance(name_or_type, RecordType) and hit[1] != name_or_type):
            raise ValueError(f"record type {name!r} is in no dialect of this set")
        return hit[0]

    def record_names(self) -> tuple[str, ...]:
        return tuple(self._by_record)

    def fingerprints(self) -> dict[str, int]:
        """Dialect name -> fingerprint, in id order (what a capture header records)."""
        return {d.name: d.fingerprint for d in self}


# ---- shared fields ---------------------------------------------------------------------

def position_cm(axis: str) -> Field:
    """A 24-bit signed position in cm (+-83.9 km) along `axis` of the shared mission frame."""
    return Field(f"{axis}_cm", 24, True, "cm", doc=f"{axis} in the shared mission frame")


SENDER = Field("sender_id", 8, unit="id", doc="robot that produced the record")

# ---- the core dialect: what every scheme sends -------------------------------------------

CORE = Dialect(CORE_DIALECT_ID, "core", (
    RecordType(
        1, "pose", 12,
        (
            SENDER, position_cm("x"), position_cm("y"),
            Field("yaw_cdeg", 16, True, "0.01 deg", -18000, 18000, "heading, counter-clockwise from +x"),
            Field("speed_cmps", 8, unit="cm/s", doc="forward speed, saturating at 255"),
            Field("exploring", 1, unit="bool", doc="has an exploration target"),
            Field("done", 1, unit="bool", doc="sees no frontier left; finished"),
            Field("returning", 1, unit="bool", doc="driving back to the start"),
            Field("vertex_count", 12, unit="vertices", doc="vertices in the sender's topological map, saturating"),
        ),
        doc="Heartbeat: where the sender is and what it is doing.",
    ),
))


def default_dialects() -> DialectSet:
    """Every dialect this firmware knows: the core plus each registered scheme's
    (firmware.schemes.all_dialects). Imported here, at call time, because the schemes'
    dialects import this module: comms never imports a scheme at module level."""
    from firmware.schemes import all_dialects
    return all_dialects()


def record_type(name_or_type: str | RecordType, dialects: DialectSet | None = None) -> RecordType:
    """A record type by name, from `dialects` (default: every known dialect)."""
    if isinstance(name_or_type, RecordType):
        return name_or_type
    return (dialects if dialects is not None else default_dialects()).record(name_or_type)


def markdown_table(dialects: DialectSet | None = None, heading_level: int = 2) -> str:
    """Every dialect's records as Markdown: for the README and `lorascout inspect --schema`.
    Dialects get headings of `heading_level`, their records one level deeper."""
    dialects = dialects if dialects is not None else default_dialects()
    h_dialect, h_record = "#" * heading_level, "#" * (heading_level + 1)
    lines = [f"Frame version {FRAME_VERSION}, {CRC_CATALOGUE_NAME} with the core fingerprint "
             f"0x{dialects.core.fingerprint:04X} and the frame dialect's fingerprint folded in.", ""]
    for d in dialects:
        lines.extend([f"{h_dialect} Dialect {d.id} `{d.name}` (fingerprint 0x{d.fingerprint:04X})", ""])
        for r in d.records:
            lines.append(f"{h_record} `{r.name}` (dialect {d.id}, code {r.code}, {r.size_bytes} bytes: "
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

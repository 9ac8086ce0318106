"""Bayer & Faigl's dialect: the 12-byte topological map vertex (Table I) on the air.

Dialect id 1. Its layout is the paper's Table I (sender, position, presence, e_inf: 89
bits) plus a 7-bit revision in what was padding, 12 bytes in all.
"""
from __future__ import annotations

import math

from firmware.comms.schema import SENDER, Dialect, Field, RecordType, position_cm
from firmware.services.topo_map import TOPO_FIELDS

DIALECT_ID = 1

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


TOPO = RecordType(
    1, "topo", 12,
    (
        SENDER, position_cm("x"), position_cm("y"), position_cm("z"),
        Field("presence", 1, unit="bool", doc="sender was at p (Table I 'presence of ID at p')"),
        Field("e_inf_code", 8, unit="16*log2(1+bit), saturating",
              doc="expected information gain at the vertex, logarithmic code"),
        Field("info_version", 7, unit="revisions", doc="how often the sender revised e_inf at this vertex, "
              "saturating at 127; the sender's highest revision counts"),
    ),
    doc="Topological map vertex, Bayer & Faigl Table I (8+72+1+8 = 89 bits), plus a 7-bit revision in "
        "what was padding so e_inf can rise again without a clock (12 B).",
)

DIALECT = Dialect(DIALECT_ID, "bayer_faigl", (TOPO,))

assert TOPO.bits_used == 96 and TOPO.size_bytes == 12  # Table I + revision
# The shared topological map folds these records as rows of its own column layout.
assert tuple(f.name for f in TOPO.fields) == TOPO_FIELDS, "topo record fields differ from TopoMap's columns"

# The highest revision a topo record can carry.
MAX_INFO_VERSION = (1 << TOPO.fields[TOPO_FIELDS.index("info_version")].bits) - 1

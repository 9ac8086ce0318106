"""WiSER-X's one record on the air, for the `lora` variant only (../shared/schemes/wiserx.md
section 5.6): a digest of the hgrid cells the sender filled by its own positions, so that
robots out of UWB and WiFi reach still know each other alive and count each other's fill.

Dialect id 4 (Bayer & Faigl 1, Meier 2, Pereira 3, MR-TopoMap 5). The spec's record type 4
of the one-table era is code 1 here, with the same fields but without its 8 spare bits: 11
bytes. Cells are numbered row-major
over the boundary's grid (row 0 at the boundary's y0, column 0 at x0), which every robot
knows at deployment: no common frame for positions is needed. Chunk k covers cells
64k .. 64k + 63, cell 64k + b in bit b of the 64-bit bitmap (bit 0 the least significant),
sent as two 32-bit fields, `bitmap_hi` (bits 32..63) then `bitmap_lo`; a grid of more than
MAX_CELLS cells has its cells beyond those never sent.
"""
from __future__ import annotations

from firmware.comms.schema import SENDER, Dialect, Field, RecordType

DIALECT_ID = 4

CELLS_PER_CHUNK = 64
MAX_CHUNKS = 16
MAX_CELLS = CELLS_PER_CHUNK * MAX_CHUNKS

HGRID = RecordType(
    1, "hgrid", 11,
    (
        SENDER,
        Field("chunk", 4, unit="index",
              doc="which 64 cells of the boundary's grid, row-major: 64 chunk .. 64 chunk + 63"),
        Field("chunks_m1", 4, unit="count - 1", doc="how many chunks the sender's grid has, less one"),
        Field("done", 1, unit="bool", doc="the sender stopped (soft or hard termination, or nothing left)"),
        Field("fill_pct", 7, unit="%", hi=100, doc="the sender's hgrid fill, all robots it counts"),
        Field("bitmap_hi", 32, unit="32 x 1 bit", doc="cell 64 chunk + 32 + b filled by the sender's own positions, "
              "in bit b"),
        Field("bitmap_lo", 32, unit="32 x 1 bit", doc="cell 64 chunk + b filled by the sender's own positions, in bit b"),
    ),
    doc="WiSER-X's hgrid digest (wiserx-lora): the sender's own filled cells, 64 a record, round robin; "
        "liveness out of UWB/WiFi reach and fill from robots never sensed (8+4+4+1+7+64 = 88 bits, 11 B).",
)

DIALECT = Dialect(DIALECT_ID, "wiserx", (HGRID,))

assert HGRID.size_bytes == 11


def chunk_fields(filled_row_major, chunk: int) -> dict[str, int]:
    """bitmap_hi and bitmap_lo of one chunk of a row-major sequence of filled flags."""
    bits = 0
    for b, on in enumerate(filled_row_major[chunk * CELLS_PER_CHUNK:(chunk + 1) * CELLS_PER_CHUNK]):
        if on:
            bits |= 1 << b
    return {"bitmap_hi": bits >> 32, "bitmap_lo": bits & 0xFFFF_FFFF}


def cells_of_chunk(chunk: int, bitmap_hi: int, bitmap_lo: int, n_cells: int) -> list[int]:
    """The cell numbers (row-major, below n_cells) a chunk's bitmap sets."""
    bitmap = bitmap_hi << 32 | bitmap_lo
    first = chunk * CELLS_PER_CHUNK
    return [first + b for b in range(CELLS_PER_CHUNK) if bitmap >> b & 1 and first + b < n_cells]

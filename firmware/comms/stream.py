"""Deframer for byte streams (a transparent serial link, a raw dump): pure, no I/O.

Frames are found by their own structure: a byte whose high nibble is our version starts a
candidate, its length byte says where the candidate ends, and the CRC decides. On a CRC
failure, or a dialect id we do not know (whose CRC cannot be checked, so garbage and a real
frame look alike), the scan advances one byte (resync), so garbage before, between or inside frames
costs only the frames it overlaps. The decision at each position depends only on the bytes
from there on, so a stream cut into chunks at any points yields the same frames.

A false candidate with a large length byte holds back what follows until enough bytes
arrived to check its CRC (at most 264); `flush()` at end of stream releases them.
"""
from __future__ import annotations

from firmware.comms.frame import LENGTH_BYTE, OVERHEAD_BYTES, DecodeResult, Reason, decode_frame
from firmware.comms.schema import FRAME_VERSION, DialectSet, default_dialects

# Candidates the scan steps over by one byte: nothing in them can be trusted.
_RESYNC = {Reason.BAD_CRC: "crc_rejects", Reason.UNKNOWN_DIALECT: "dialect_rejects"}


class Deframer:
    def __init__(self, dialects: DialectSet | None = None) -> None:
        """dialects: what to decode (default: every dialect this firmware knows)."""
        self.dialects = dialects if dialects is not None else default_dialects()
        self._buf = bytearray()
        # Invariant: bytes_in == bytes_skipped + bytes_framed + pending_bytes.
        self.stats: dict[str, int] = {"bytes_in": 0, "bytes_skipped": 0, "bytes_framed": 0, "frames": 0,
                                      "crc_rejects": 0, "dialect_rejects": 0}

    def feed(self, chunk: bytes) -> list[DecodeResult]:
        """Add bytes; return the frames completed by them (CRC-valid, in stream order;
        a frame whose CRC is right but whose content is not comes with its reason)."""
        self._buf += chunk
        self.stats["bytes_in"] += len(chunk)
        return self._scan(final=False)

    def flush(self) -> list[DecodeResult]:
        """End of stream: resolve candidates still waiting for bytes that will never come."""
        out = self._scan(final=True)
        self.stats["bytes_skipped"] += len(self._buf)
        self._buf.clear()
        return out

    @property
    def pending_bytes(self) -> int:
        return len(self._buf)

    def _scan(self, final: bool) -> list[DecodeResult]:
        buf, out, pos, n = self._buf, [], 0, len(self._buf)
        while pos < n:
            if buf[pos] >> 4 != FRAME_VERSION:
                pos += 1
                self.stats["bytes_skipped"] += 1
                continue
            if n - pos <= LENGTH_BYTE:
                break
            want = OVERHEAD_BYTES + buf[pos + LENGTH_BYTE]
            if n - pos < want:
                if not final:
                    break
                pos += 1
                self.stats["bytes_skipped"] += 1
                continue
            res = decode_frame(bytes(buf[pos:pos + want]), self.dialects)
            if res.reason in _RESYNC:
                pos += 1
                self.stats["bytes_skipped"] += 1
                self.stats[_RESYNC[res.reason]] += 1
                continue
            out.append(res)
            self.stats["frames"] += 1
            self.stats["bytes_framed"] += want
            pos += want
        del buf[:pos]
        return out

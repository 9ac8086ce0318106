"""Bytes on the air: the record dialects (schema), record codec, frames, stream deframer and
the link layer (aggregation, duplicate suppression, relay, duty-cycle budget)."""
from firmware.comms.codec import REASONS, Reason, decode, encode
from firmware.comms.frame import DecodeResult, Frame, decode_frame, encode_frame, seq_newer
from firmware.comms.link import LinkLayer
from firmware.comms.schema import CORE, Dialect, DialectSet, markdown_table
from firmware.comms.stream import Deframer

__all__ = [
    "REASONS", "Reason", "decode", "encode", "DecodeResult", "Frame", "decode_frame",
    "encode_frame", "seq_newer", "LinkLayer", "CORE", "Dialect", "DialectSet", "markdown_table",
    "Deframer",
]

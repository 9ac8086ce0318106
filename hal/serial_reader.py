"""The reader-thread side that the byte-stream serial backends share (pyserial's threaded
helpers): every chunk read from the port, and the end of the connection, handed to the
backend's own methods on the reader thread."""
from __future__ import annotations

from collections.abc import Callable

import serial.threaded


class Forwarding(serial.threaded.Protocol):
    def __init__(self, on_bytes: Callable[[bytes], None], on_lost: Callable[[BaseException | None], None]):
        self._on_bytes = on_bytes
        self._on_lost = on_lost

    def data_received(self, data: bytes) -> None:
        self._on_bytes(data)

    def connection_lost(self, exc) -> None:
        self._on_lost(exc)


def start_reader(port, on_bytes: Callable[[bytes], None],
                 on_lost: Callable[[BaseException | None], None]) -> serial.threaded.ReaderThread:
    """A started ReaderThread on `port` that forwards to on_bytes and on_lost."""
    reader = serial.threaded.ReaderThread(port, lambda: Forwarding(on_bytes, on_lost))
    reader.start()
    return reader

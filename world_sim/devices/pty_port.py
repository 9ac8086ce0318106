"""One emulated device's end of a serial line: a raw pseudo-terminal pair served by a thread.

The client (a driver, pyserial, minicom) opens `path`, the slave side. Whatever it writes
is handed to `on_input(bytes)` on the service thread as it arrives; `write` queues bytes to
the client and never blocks: what the pty cannot take yet waits in a buffer that the
service thread keeps draining. `bytes_queued` counts every byte ever queued, which is what
a lockstep driver waits for (hal.rplidar.RplidarLidar.sync).

The port keeps the slave open itself, so a client that closes and reopens the device does
not make the master report end-of-file (as radio_sim.virtual_modem does for the modems).
"""
from __future__ import annotations

import errno
import os
import select
import termios
import threading
import tty
from collections.abc import Callable

_READ_CHUNK = 4096


class PtyPort:
    def __init__(self, on_input: Callable[[bytes], None], baudrate: int, name: str):
        self._on_input = on_input
        self.master, self.slave = os.openpty()
        try:
            make_raw(self.slave, baudrate)
            os.set_blocking(self.master, False)
            self._wake_r, self._wake_w = os.pipe()
        except BaseException:
            os.close(self.master)
            os.close(self.slave)
            raise
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self.path = os.ttyname(self.slave)
        self._lock = threading.Lock()
        self._out = bytearray()
        self._bytes_queued = 0
        self._closed = False
        self.error: BaseException | None = None      # what stopped the service thread, if anything
        self._thread = threading.Thread(target=self._serve, name=name, daemon=True)
        self._thread.start()

    @property
    def bytes_queued(self) -> int:
        with self._lock:
            return self._bytes_queued

    def write(self, data: bytes) -> None:
        """Queue bytes to the client (any thread); never blocks."""
        with self._lock:
            if self._closed:
                return
            self._out += data
            self._bytes_queued += len(data)
            self._flush_locked()
            left_over = bool(self._out)
        if left_over:
            self._wake()

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._wake()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        for fd in (self.master, self.slave, self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass

    # -- service thread ---------------------------------------------------------------
    def _serve(self) -> None:
        try:
            while not self._closed:
                self._serve_once()
        except BaseException as e:  # surfaced by the emulator's next advance_to
            self.error = e

    def _serve_once(self) -> None:
        with self._lock:
            writers = [self.master] if self._out else []
        try:
            readable, _, _ = select.select([self.master, self._wake_r], writers, [], None)
        except (OSError, ValueError):
            if self._closed:
                return
            raise
        if self._closed:
            return
        if self._wake_r in readable:
            _drain(self._wake_r)
        if self.master in readable:
            data = self._read()
            if data:
                self._on_input(data)
        with self._lock:
            self._flush_locked()

    def _read(self) -> bytes:
        return read_master(self.master)

    def _flush_locked(self) -> None:
        write_to_master(self.master, self._out)

    def _wake(self) -> None:
        try:
            os.write(self._wake_w, b"\0")
        except OSError:
            pass


def read_master(master: int) -> bytes:
    """What the client has written so far (non-blocking master): b'' if nothing, or if no
    client has the slave open."""
    try:
        return os.read(master, _READ_CHUNK)
    except (BlockingIOError, InterruptedError):
        return b""
    except OSError as e:
        if e.errno == errno.EIO:       # no client has the slave open
            return b""
        raise


def write_to_master(master: int, out: bytearray) -> None:
    """Write as much of `out` as the pty takes now and remove it from `out`; with the pty
    gone (or no client) the bytes are dropped."""
    while out:
        try:
            n = os.write(master, out)
        except BlockingIOError:
            return
        except OSError as e:
            if e.errno in (errno.EIO, errno.EBADF):
                out.clear()
                return
            raise
        del out[:n]


def make_raw(fd: int, baudrate: int) -> None:
    """8N1 raw mode at a nominal baud rate (a pty ignores the rate; clients check it)."""
    tty.setraw(fd)
    attrs = termios.tcgetattr(fd)
    speed = getattr(termios, f"B{baudrate}")
    attrs[4] = attrs[5] = speed
    attrs[2] = (attrs[2] & ~(termios.CSIZE | termios.PARENB | termios.CSTOPB)) | termios.CS8 | termios.CLOCAL \
        | termios.CREAD
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


def _drain(fd: int) -> None:
    try:
        while os.read(fd, 512):
            pass
    except BlockingIOError:
        pass

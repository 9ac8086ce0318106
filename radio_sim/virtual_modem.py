"""Virtual RN2483 (or, for the US band, RN2903) modems on real pseudo-terminals, all on one
shared Channel.

Each modem is a pty pair: the client (a real modem driver, pyserial, minicom) opens the
slave path; the bank reads command lines from the master, answers them through the pure
state machine in radio_sim.rn2483, and writes the module's asynchronous lines
(`radio_tx_ok`, `radio_rx  <HEX>`, `radio_err`) when the Channel or a module timer says so.

Two ways to drive time (the bank itself never reads a clock):

- Lockstep (`ModemBank(...)` then `advance_to(now_us)`): the mission runner owns time.
  A service thread answers commands at the bank's current time, which moves only in
  `advance_to`. The drivers (hal.rn2483.Rn2483Modem) do their I/O on their own threads, so
  the runner hands time over in three steps (`LockstepSerialRadios.advance_to`): every
  driver settles (all commands the firmware queued during the tick are answered, so the
  bank served them at the tick's time), then the bank advances, then every driver syncs
  (a barrier query: lines written by `advance_to` go into the same ordered byte stream
  before its reply, so once the reply is in, every event up to the new time has been read,
  whatever the kernel's pty scheduling does). A lock keeps `advance_to` and the service
  thread apart anyway.
- Wall clock (`serve(now_us_fn, should_stop)`): for `lorascout modem`. The caller passes
  the clock; the loop sleeps in select() until a command arrives or the Channel or a
  module timer is due.

The bank keeps each slave open itself, so a client that closes and reopens the device
does not make the master report end-of-file, and writes never block: output waits in a
per-modem buffer until the pty takes it.
"""
from __future__ import annotations

import os
import select
import threading
from collections.abc import Callable, Sequence

from hal import rn2483_protocol as P
from hal.lora import PRIVATE_SYNC_WORD, AirInterface, RadioProfile
from radio_sim.rn2483 import Rn2483, on_air_settings
from world_sim.devices.pty_port import make_raw, read_master, write_to_master

_MAX_PENDING_INPUT = 4096   # bytes of an unterminated line kept before it is answered as invalid


class _ChannelPort:
    """Binds one modem to its node id on the shared Channel."""

    def __init__(self, channel, node_id: int):
        self._channel = channel
        self._node_id = node_id

    def transmit(self, payload: bytes, now_us: int, air: AirInterface, tx_power_dbm: float) -> int | None:
        return self._channel.transmit(self._node_id, payload, now_us, air=air, tx_power_dbm=tx_power_dbm)

    def set_listening(self, listening: bool, now_us: int, air: AirInterface) -> None:
        self._channel.set_listening(self._node_id, listening, now_us, air=air)


class _Pty:
    def __init__(self, baudrate: int):
        self.master, self.slave = os.openpty()
        make_raw(self.slave, baudrate)                     # nominal 57600 8N1: ptys ignore the rate
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.inbuf = bytearray()
        self.outbuf = bytearray()

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass


class ModemBank:
    """N virtual RN2483 modems sharing `channel`, one per node id (RN2903 modems when the
    profile is in the US 902-928 MHz band).

    Each modem's board radiates `radio set pwr` plus a fixed front-end gain chosen so that a
    modem configured for the profile (hal.rn2483_protocol.network_config_commands) radiates
    the profile's power (eu868-g3's 27 dBm is the module's 15 dBm and a 12 dB amplifier):
    then the serial path and the in-process modems give the same air, and `radio set pwr`
    moves a modem's power from there, dB for dB.

    The caller attaches the node ids to the Channel (positions are its business) before
    making the bank, and from then on leaves the Channel's time and events to the bank:
    call `bank.advance_to`, never `channel.take_events` for these nodes. In
    lockstep mode (`lockstep=True`, the default) a daemon thread serves commands at once;
    the runner moves time with `advance_to`. With `lockstep=False` nothing runs until the
    caller calls `serve`.
    """

    def __init__(self, channel, profile: RadioProfile, node_ids: Sequence[int], *,
                 lockstep: bool = True, start_us: int = 0, sync_word: int = PRIVATE_SYNC_WORD,
                 baudrate: int = 57600):
        if len(set(node_ids)) != len(node_ids):
            raise ValueError(f"node_ids must be distinct, got {list(node_ids)}")
        self._channel = channel
        self.model = P.model_for_freq(profile.freq_hz) or P.RN2483
        self._on_air = on_air_settings(profile, sync_word, self.model)
        gain_db = profile.tx_power_dbm - self._on_air.pwr_dbm
        self.node_ids = tuple(node_ids)
        self.modems = [Rn2483(n, _ChannelPort(channel, n), self._on_air, model=self.model,
                              ideal_link=profile.ideal, front_end_gain_db=gain_db)
                       for n in self.node_ids]
        self._ptys: list[_Pty] = []
        try:
            for _ in self.node_ids:
                self._ptys.append(_Pty(baudrate))
        except BaseException:
            self._close_fds()
            raise
        # A module after power-on is not receiving (the Channel arms nodes when attached);
        # the driver's `radio rx 0` arms them again at its own time.
        start_us = max(start_us, getattr(channel, "now_us", start_us))
        for n in self.node_ids:
            channel.set_listening(n, False, start_us)
        self._by_master = {p.master: i for i, p in enumerate(self._ptys)}
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._lock = threading.RLock()
        self._now_us = start_us
        self._closed = False
        self.commands_served = 0
        self._thread: threading.Thread | None = None
        self._thread_error: BaseException | None = None
        if lockstep:
            self._thread = threading.Thread(target=self._service_thread, name="rn2483-bank", daemon=True)
            self._thread.start()

    # -- public ------------------------------------------------------------------
    @property
    def paths(self) -> list[str]:
        """Device paths of the modems, in node id order; open them with pyserial."""
        return [p.path for p in self._ptys]

    @property
    def now_us(self) -> int:
        return self._now_us

    def advance_to(self, now_us: int) -> None:
        """Move the bank and the Channel to `now_us`: frames that ended and module timers
        that fell due are resolved in time order and their lines queued to the clients."""
        if self._thread_error is not None:
            raise RuntimeError(f"virtual modem service thread failed: {self._thread_error!r}") from self._thread_error
        with self._lock:
            if now_us < self._now_us:
                raise ValueError(f"time runs forwards: advance_to({now_us}) after {self._now_us}")
            self._step_to(now_us)
            self._flush_all()
            left_over = any(p.outbuf for p in self._ptys)
        if left_over and self._thread is not None:
            self._wake()   # the service thread writes the rest when the pty has room

    def next_due_us(self) -> int | None:
        """The earliest time at which the bank has something to do, or None."""
        with self._lock:
            times = [m.next_deadline_us() for m in self.modems]
            times.append(self._channel.next_event_us())
            times = [t for t in times if t is not None]
            return min(times) if times else None

    def serve(self, now_us_fn: Callable[[], int], should_stop: Callable[[], bool],
              max_sleep_s: float = 0.5) -> None:
        """Wall-clock service loop for `lorascout modem`: returns when should_stop() is true
        (call `wake()` from a signal handler to make it look promptly)."""
        if self._thread is not None:
            raise RuntimeError("serve() is for a bank made with lockstep=False")
        while not should_stop() and not self._closed:
            now_us = now_us_fn()
            self.advance_to(max(now_us, self._now_us))
            due_us = self.next_due_us()
            timeout_s = max_sleep_s
            if due_us is not None:
                timeout_s = min(max_sleep_s, max(0.0, (due_us - now_us_fn()) / 1e6))
            self._service_once(timeout_s, now_us_fn)

    def wake(self) -> None:
        self._wake()

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._wake()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)
        self._close_fds()

    def __enter__(self) -> ModemBank:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- time ---------------------------------------------------------------------
    def _step_to(self, now_us: int) -> None:
        # Module timers may end a reception before a frame that ends later: walk the
        # deadlines in order so the Channel sees each `stop listening` at its own time.
        while True:
            due = [m.next_deadline_us() for m in self.modems]
            due = [t for t in due if t is not None and t <= now_us]
            if not due:
                break
            t = min(due)
            self._channel.advance_to(t)
            self._now_us = max(self._now_us, t)
            self._dispatch_channel_events()
            for i, m in enumerate(self.modems):
                self._emit(i, m.expire(t))
        self._channel.advance_to(now_us)
        self._now_us = now_us
        self._dispatch_channel_events()

    def _dispatch_channel_events(self) -> None:
        for i, (node_id, m) in enumerate(zip(self.node_ids, self.modems)):
            for event in self._channel.take_events(node_id):
                self._emit(i, m.deliver(event, self._now_us))

    # -- bytes ----------------------------------------------------------------------
    def _emit(self, i: int, lines: list[str]) -> None:
        if lines:
            self._ptys[i].outbuf += "".join(line + "\r\n" for line in lines).encode("ascii")

    def _flush_all(self) -> None:
        for p in self._ptys:
            self._flush(p)

    def _flush(self, p: _Pty) -> None:
        write_to_master(p.master, p.outbuf)

    def _handle_input(self, i: int, now_us: int) -> None:
        p = self._ptys[i]
        data = read_master(p.master)
        if not data:
            return
        p.inbuf += data
        while True:
            nl = p.inbuf.find(b"\n")
            if nl < 0:
                break
            raw = bytes(p.inbuf[:nl]).rstrip(b"\r")
            del p.inbuf[: nl + 1]
            line = raw.decode("ascii", errors="replace")
            self._emit(i, self.modems[i].command(line, now_us))
            self.commands_served += 1
            # A command can finish something at once: arming hands over an injected duplicate
            # that waited for the receiver, and a zero-length frame of the ideal profile ends
            # when it starts. Resolve it now, as the in-process modem's next call would.
            self._channel.advance_to(self._now_us)
            self._dispatch_channel_events()
        if len(p.inbuf) > _MAX_PENDING_INPUT:
            # The module's line buffer overflows on an endless line: it answers invalid_param.
            p.inbuf.clear()
            self._emit(i, ["invalid_param"])

    def _service_once(self, timeout_s: float | None, now_us_fn: Callable[[], int] | None = None) -> None:
        with self._lock:
            if self._closed:
                return
            readers = [p.master for p in self._ptys] + [self._wake_r]
            writers = [p.master for p in self._ptys if p.outbuf]
        try:
            readable, writable, _ = select.select(readers, writers, [], timeout_s)
        except (OSError, ValueError):
            if self._closed:
                return
            raise
        with self._lock:
            if self._closed:
                return
            if self._wake_r in readable:
                try:
                    while os.read(self._wake_r, 512):
                        pass
                except BlockingIOError:
                    pass
            if now_us_fn is not None:
                # Wall clock: resolve what fell due before answering, so a command sees the
                # air as it is now.
                self._step_to(max(now_us_fn(), self._now_us))
            for fd in readable:
                i = self._by_master.get(fd)
                if i is not None:
                    self._handle_input(i, self._now_us)
            self._flush_all()

    def _service_thread(self) -> None:
        try:
            while not self._closed:
                self._service_once(None)
        except BaseException as e:  # surfaced to the runner by the next advance_to
            self._thread_error = e

    def _wake(self) -> None:
        try:
            os.write(self._wake_w, b"\0")
        except (BlockingIOError, OSError):
            pass

    def _close_fds(self) -> None:
        for p in self._ptys:
            p.close()
        for fd in (getattr(self, "_wake_r", None), getattr(self, "_wake_w", None)):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass


class LockstepSerialRadios:
    """A ModemBank and the drivers talking to it, advanced together (see the module
    docstring): `advance_to` settles every driver, advances the bank, then syncs every
    driver, so the next firmware tick sees everything up to the new time and nothing more."""

    def __init__(self, bank: ModemBank, radios: list):
        self.bank = bank
        self.radios = radios

    @property
    def now_us(self) -> int:
        return self.bank.now_us

    def advance_to(self, now_us: int) -> None:
        for r in self.radios:
            r.settle()
        self.bank.advance_to(now_us)
        for r in self.radios:
            r.sync()

    def close(self) -> None:
        for r in self.radios:
            r.close()
        self.bank.close()


def open_serial_radios(channel, profile: RadioProfile, clock, node_ids: Sequence[int],
                       **modem_kwargs) -> tuple[LockstepSerialRadios, list]:
    """Lockstep serial radios for a mission: one virtual modem per node id (already attached
    to `channel`), each driven by hal.rn2483.Rn2483Modem over its pty in lockstep mode.
    Returns (link, radios); call link.advance_to(clock.now_us()) between rounds of firmware
    ticks, and link.close() at the end (it closes the radios too)."""
    from hal.rn2483 import Rn2483Modem

    bank = ModemBank(channel, profile, node_ids, start_us=clock.now_us())
    radios: list = []
    try:
        for path in bank.paths:
            radios.append(Rn2483Modem(path, profile, clock, lockstep=True, **modem_kwargs))
    except BaseException:
        for r in radios:
            r.close()
        bank.close()
        raise
    return LockstepSerialRadios(bank, radios), radios

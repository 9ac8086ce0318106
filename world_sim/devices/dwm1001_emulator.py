"""An emulated Qorvo (Decawave) DWM1001 on a pseudo-terminal, ranging for one robot of the
simulated world over the UART TLV API (hal.dwm1001_protocol).

The module is a PANS tag by default (`node_is_anchor=False`): dwm_loc_get reports its
distances to the other robots' modules, as anchors, at most four (the nearest, as a tag
picks the anchors it hears best), each with its quality factor and a configured position
that is unknown (zeros, quality 0: anchors on moving robots have none); its own position is
unknown too. As an anchor it reports its distances to up to fifteen tags instead. Addresses
follow the emulated team's plan (robot r is `robot_address(r)`). Distances are whole
millimetres, as the module reports them.

Answered: dwm_loc_get, dwm_status_get (bit 0 new location data since the last dwm_loc_get,
bit 1 joined), dwm_cfg_get, dwm_ver_get, dwm_pos_get, dwm_upd_rate_get/set, dwm_reset.
Other requests the API defines are answered with return code 1 (as an unknown command),
and so is a frame that cannot be one (an unknown type or a wrong length); the emulator then
drops what it had received, as the module drops a broken frame.

Time: the emulator never reads a clock. `advance_to(now_us)`, called by the simulation
runner after each world step, takes the world's new UWB measurements of this robot (only
the newest round: the module reports its last result) and raises the status bit; requests are
answered at once by the port's service thread.
"""
from __future__ import annotations

import struct
import threading

from hal import dwm1001_protocol as P
from world_sim.devices.pty_port import PtyPort
from world_sim.world import World

FIRMWARE_VERSION = 0x01030000       # the emulator's own version numbers, in the API's layout
CONFIG_VERSION = 0x00070100
HARDWARE_VERSION = 0xDECA0302
RANGE_QUALITY = 100
DEFAULT_UPDATE_RATE_100MS = 1       # 10 Hz, PANS's fastest tag rate


class Dwm1001Emulator:
    """Robot `robot_index`'s UWB module, as a DWM1001 on the pty at `path`."""

    def __init__(self, world: World, robot_index: int, *, node_is_anchor: bool = False,
                 baudrate: int = P.BAUDRATE):
        world.command(robot_index)          # validates the index now
        self._world = world
        self._index = robot_index
        self.node_is_anchor = node_is_anchor
        self._lock = threading.Lock()
        self._requests = P.RequestReader()
        self._latest_m: dict[int, float] = {}       # peer robot -> its newest distance
        self.loc_ready = False
        self.update_rate_100ms = (DEFAULT_UPDATE_RATE_100MS, DEFAULT_UPDATE_RATE_100MS)   # moving, stationary
        self.requests_served = 0
        self._port = PtyPort(self._on_input, baudrate, f"dwm1001-emulator {robot_index}")

    @property
    def path(self) -> str:
        return self._port.path

    @property
    def address(self) -> int:
        return P.robot_address(self._index)

    def advance_to(self, now_us: int) -> None:
        """Take the world's UWB measurements of this robot up to now."""
        if self._port.error is not None:
            raise RuntimeError(f"DWM1001 emulator {self._index}: service thread failed: "
                               f"{self._port.error!r}") from self._port.error
        measured = self._world.take_uwb_ranges(self._index)
        if not measured:
            return
        newest_us = max(r.stamp_us for r in measured)
        with self._lock:
            # The module reports its last ranging round: peers it did not hear then are gone.
            self._latest_m = {r.peer_id: r.range_m for r in measured if r.stamp_us == newest_us}
            self.loc_ready = True

    def close(self) -> None:
        self._port.close()

    def __enter__(self) -> Dwm1001Emulator:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- service thread -----------------------------------------------------------------
    def _on_input(self, data: bytes) -> None:
        with self._lock:
            for req in self._requests.feed(data):
                self.requests_served += 1
                self._port.write(self._answer(req))

    def _answer(self, req: P.Request | None) -> bytes:
        if req is None:
            return P.return_value(P.RV_ERR_TLV)
        ok = P.return_value(P.RV_OK)
        if req.cmd == P.CMD_LOC_GET:
            self.loc_ready = False
            return ok + P.encode_location(self._location())
        if req.cmd == P.CMD_STATUS_GET:
            return ok + P.encode_status((P.STATUS_LOC_READY if self.loc_ready else 0) | P.STATUS_UWBMAC_JOINED)
        if req.cmd == P.CMD_CFG_GET:
            return ok + P.encode_cfg(self.node_is_anchor)
        if req.cmd == P.CMD_VER_GET:
            return ok + b"".join(P.tlv(t, struct.pack("<I", v)) for t, v in (
                (P.TLV_FW_VER, FIRMWARE_VERSION), (P.TLV_CFG_VER, CONFIG_VERSION), (P.TLV_HW_VER, HARDWARE_VERSION)))
        if req.cmd == P.CMD_POS_GET:
            return ok + P.tlv(P.TLV_POS_XYZ, P.Position().encode())
        if req.cmd == P.CMD_UR_GET:
            return ok + P.tlv(P.TLV_UR, struct.pack("<HH", *self.update_rate_100ms))
        if req.cmd == P.CMD_UR_SET:
            self.update_rate_100ms = struct.unpack("<HH", req.value)
            return ok
        if req.cmd == P.CMD_RESET:
            self._latest_m.clear()
            self.loc_ready = False
            return ok
        return P.return_value(P.RV_ERR_TLV)

    def _location(self) -> P.Location:
        limit = P.ANCHOR_MAX_TAGS if self.node_is_anchor else P.TAG_MAX_ANCHORS
        nearest = sorted(self._latest_m.items(), key=lambda kv: (kv[1], kv[0]))[:limit]
        distances = tuple(P.Distance(P.robot_address(peer), round(range_m * 1000.0), RANGE_QUALITY,
                                     None if self.node_is_anchor else P.Position())
                          for peer, range_m in sorted(nearest))
        return P.Location(P.Position(), distances, node_is_anchor=self.node_is_anchor)

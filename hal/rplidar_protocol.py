"""The Slamtec RPLIDAR A-series serial protocol, in one place: requests, response
descriptors, answer layouts, the measurement node, the angle convention, and a byte-stream
parser. The driver (hal.rplidar) and the emulator (world_sim.devices.rplidar_emulator) both
take them from here. Pure: no I/O, no clock.

Source: Slamtec "RPLIDAR Interface Protocol and Application Notes" (LR001, protocol v2.x)
and the Slamtec SDK's protocol header. 115200 8N1 for the A1 and A2 (the A3 runs at 256000).

- A request is `A5 CMD`, or, for commands with bit 7 set, `A5 CMD SIZE PAYLOAD CHECKSUM`
  (the checksum is the XOR of every byte before it).
- An answer starts with a 7-byte descriptor `A5 5A`, a little-endian u32 holding the
  payload length (30 bits) and the send mode (2 bits: 0 one response, 1 a stream of them),
  and the answer type. STOP, RESET and SET_MOTOR_PWM have no answer; RESET reboots the core,
  which prints a text banner.
- SCAN (and FORCE_SCAN) stream 5-byte measurement nodes (see `encode_nodes`).

The parser resynchronises on its own: a node is checked by its redundant start bits and its
check bit, a descriptor by its sync bytes and a known (length, mode, type), and the node
stream is only trusted again after `LOCK_NODES` consecutive good nodes. `A5 5A` can never
start a valid node (0x5A has its check bit clear), so a descriptor is always recognised,
even in the middle of a node stream. Random bytes never make it raise.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

BAUDRATE = 115200

SYNC_BYTE = 0xA5
SYNC_BYTE2 = 0x5A
CMDFLAG_HAS_PAYLOAD = 0x80

# -- requests (host -> device) ---------------------------------------------------------
CMD_STOP = 0x25
CMD_RESET = 0x40
CMD_SCAN = 0x20
CMD_FORCE_SCAN = 0x21
CMD_EXPRESS_SCAN = 0x82
CMD_GET_INFO = 0x50
CMD_GET_HEALTH = 0x52
CMD_GET_SAMPLERATE = 0x59
CMD_GET_LIDAR_CONF = 0x84
CMD_SET_MOTOR_PWM = 0xF0            # A2/A3 accessory board; the A1's motor runs off DTR

MAX_MOTOR_PWM = 1023
DEFAULT_MOTOR_PWM = 660

# -- answers (device -> host) ------------------------------------------------------------
DESCRIPTOR_BYTES = 7
SEND_MODE_SINGLE = 0
SEND_MODE_MULTI = 1
ANS_TYPE_DEVINFO = 0x04
ANS_TYPE_DEVHEALTH = 0x06
ANS_TYPE_SAMPLE_RATE = 0x15
ANS_TYPE_MEASUREMENT = 0x81
ANS_TYPE_MEASUREMENT_CAPSULED = 0x82

INFO_BYTES = 20                     # model, firmware minor, firmware major, hardware, 16-byte serial
HEALTH_BYTES = 3                    # status, error code u16 LE
SAMPLE_RATE_BYTES = 4               # standard and express sample durations, u16 LE microseconds
NODE_BYTES = 5
CAPSULE_BYTES = 84                  # the express scan's legacy capsule (not decoded here)

# The answers this project knows, by type: (payload length, send mode). A descriptor that
# is not one of these is taken for noise.
ANSWERS: dict[int, tuple[int, int]] = {
    ANS_TYPE_DEVINFO: (INFO_BYTES, SEND_MODE_SINGLE),
    ANS_TYPE_DEVHEALTH: (HEALTH_BYTES, SEND_MODE_SINGLE),
    ANS_TYPE_SAMPLE_RATE: (SAMPLE_RATE_BYTES, SEND_MODE_SINGLE),
    ANS_TYPE_MEASUREMENT: (NODE_BYTES, SEND_MODE_MULTI),
    ANS_TYPE_MEASUREMENT_CAPSULED: (CAPSULE_BYTES, SEND_MODE_MULTI),
}

HEALTH_GOOD, HEALTH_WARNING, HEALTH_ERROR = 0, 1, 2
HEALTH_NAMES = {HEALTH_GOOD: "good", HEALTH_WARNING: "warning", HEALTH_ERROR: "error"}

# -- measurement node ---------------------------------------------------------------------
ANGLE_Q6_PER_DEG = 64               # angle in 1/64 degree
DISTANCE_Q2_PER_MM = 4              # distance in 1/4 millimetre; 0 = no valid return
FULL_TURN_Q6 = 360 * ANGLE_Q6_PER_DEG
MAX_DISTANCE_Q2 = 0xFFFF            # the field's limit: 16.383 m
QUALITY_MAX = 63

# The parser trusts a node stream again only after this many good nodes in a row.
LOCK_NODES = 3


# -- angle convention -----------------------------------------------------------------------
# The device measures its angle clockwise seen from above, 0 degrees along its front; the
# robot frame is counter-clockwise from +x. Mounted with its 0 degrees along the robot's +x
# (the mounting this project assumes), a device angle theta is the robot angle -theta.

def device_angle_q6(robot_angle_rad: np.ndarray) -> np.ndarray:
    """Device angles (q6, 0 <= a < 360 * 64) of beams at these robot-frame angles."""
    deg = np.degrees(-np.asarray(robot_angle_rad, dtype=np.float64))
    return np.rint(deg * ANGLE_Q6_PER_DEG).astype(np.int64) % FULL_TURN_Q6


def robot_angle_rad(angle_q6: np.ndarray) -> np.ndarray:
    """Robot-frame angles in (-pi, pi] of nodes at these device angles (q6)."""
    rad = -np.radians(np.asarray(angle_q6, dtype=np.float64) / ANGLE_Q6_PER_DEG)
    return (rad + math.pi) % (2.0 * math.pi) - math.pi


# -- requests -------------------------------------------------------------------------------

def request(cmd: int, payload: bytes = b"") -> bytes:
    """The bytes of one request. Commands with bit 7 set carry a payload (possibly empty)
    with its size and checksum; the others carry none."""
    if not cmd & CMDFLAG_HAS_PAYLOAD:
        if payload:
            raise ValueError(f"command 0x{cmd:02X} takes no payload")
        return bytes((SYNC_BYTE, cmd))
    if len(payload) > 255:
        raise ValueError(f"payload of {len(payload)} bytes does not fit the size byte")
    head = bytes((SYNC_BYTE, cmd, len(payload))) + payload
    return head + bytes((xor_checksum(head),))


def xor_checksum(data: bytes) -> int:
    c = 0
    for b in data:
        c ^= b
    return c


def motor_pwm_payload(pwm: int) -> bytes:
    if not 0 <= pwm <= MAX_MOTOR_PWM:
        raise ValueError(f"motor PWM must be 0..{MAX_MOTOR_PWM}, got {pwm}")
    return struct.pack("<H", pwm)


@dataclass(frozen=True)
class Request:
    cmd: int
    payload: bytes = b""


class RequestParser:
    """The device's side: splits the host's bytes into requests. Bytes before a sync byte
    are dropped; a payload request with a wrong checksum is dropped whole (the device
    ignores it). Never raises."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self.bytes_dropped = 0
        self.bad_checksums = 0

    def feed(self, data: bytes) -> list[Request]:
        self._buf += data
        out: list[Request] = []
        while True:
            start = self._buf.find(SYNC_BYTE)
            if start < 0:
                self.bytes_dropped += len(self._buf)
                self._buf.clear()
                return out
            if start:
                self.bytes_dropped += start
                del self._buf[:start]
            if len(self._buf) < 2:
                return out
            cmd = self._buf[1]
            if not cmd & CMDFLAG_HAS_PAYLOAD:
                out.append(Request(cmd))
                del self._buf[:2]
                continue
            if len(self._buf) < 3 or len(self._buf) < 4 + self._buf[2]:
                return out
            size = self._buf[2]
            frame = bytes(self._buf[: 4 + size])
            if xor_checksum(frame[:-1]) != frame[-1]:
                self.bad_checksums += 1
                del self._buf[:1]          # look for the next sync byte inside it
                continue
            out.append(Request(cmd, frame[3:3 + size]))
            del self._buf[: 4 + size]


# -- answers ----------------------------------------------------------------------------------

def descriptor(answer_type: int) -> bytes:
    length, mode = ANSWERS[answer_type]
    return bytes((SYNC_BYTE, SYNC_BYTE2)) + struct.pack("<I", length | (mode << 30)) + bytes((answer_type,))


@dataclass(frozen=True)
class DeviceInfo:
    model: int
    firmware_major: int
    firmware_minor: int
    hardware: int
    serial_number: bytes            # 16 bytes

    def encode(self) -> bytes:
        return bytes((self.model, self.firmware_minor, self.firmware_major, self.hardware)) + self.serial_number

    @classmethod
    def decode(cls, payload: bytes) -> DeviceInfo:
        return cls(model=payload[0], firmware_minor=payload[1], firmware_major=payload[2], hardware=payload[3],
                   serial_number=bytes(payload[4:INFO_BYTES]))

    @property
    def serial_hex(self) -> str:
        """The serial number as Slamtec's tools print it (bytes in reverse order)."""
        return self.serial_number[::-1].hex().upper()


@dataclass(frozen=True)
class Health:
    status: int                     # HEALTH_GOOD, HEALTH_WARNING or HEALTH_ERROR
    error_code: int

    def encode(self) -> bytes:
        return struct.pack("<BH", self.status, self.error_code)

    @classmethod
    def decode(cls, payload: bytes) -> Health | None:
        status, code = struct.unpack("<BH", payload[:HEALTH_BYTES])
        return cls(status, code) if status in HEALTH_NAMES else None


@dataclass(frozen=True)
class SampleRate:
    standard_us: int                # time per sample in SCAN
    express_us: int                 # time per sample in EXPRESS_SCAN

    def encode(self) -> bytes:
        return struct.pack("<HH", self.standard_us, self.express_us)

    @classmethod
    def decode(cls, payload: bytes) -> SampleRate:
        return cls(*struct.unpack("<HH", payload[:SAMPLE_RATE_BYTES]))


@dataclass(frozen=True)
class StreamStarted:
    """A descriptor that opened a stream of answers (a scan started)."""

    answer_type: int


@dataclass(frozen=True, eq=False)
class Nodes:
    """Consecutive measurement nodes, decoded, in arrival order."""

    start: np.ndarray               # bool: first node of a new revolution
    quality: np.ndarray             # uint8, 0..63
    angle_q6: np.ndarray            # int64, device angle in 1/64 degree
    distance_q2: np.ndarray         # int64, 1/4 mm; 0 = no valid return

    def __len__(self) -> int:
        return len(self.start)


Answer = DeviceInfo | Health | SampleRate | StreamStarted | Nodes


def encode_nodes(start: np.ndarray, quality: np.ndarray, angle_q6: np.ndarray, distance_q2: np.ndarray) -> bytes:
    """Measurement nodes as the device sends them:
    byte 0: quality (6 bits) << 2 | not-start << 1 | start;
    byte 1: angle_q6 bits 0-6 << 1 | check bit (always 1); byte 2: angle_q6 bits 7-14;
    bytes 3-4: distance_q2, little-endian."""
    start = np.asarray(start, dtype=bool)
    q = np.asarray(quality, dtype=np.int64) & QUALITY_MAX
    a = np.asarray(angle_q6, dtype=np.int64) & 0x7FFF
    d = np.asarray(distance_q2, dtype=np.int64) & 0xFFFF
    out = np.empty((len(start), NODE_BYTES), dtype=np.uint8)
    out[:, 0] = (q << 2) | ((~start).astype(np.int64) << 1) | start.astype(np.int64)
    out[:, 1] = ((a & 0x7F) << 1) | 1
    out[:, 2] = a >> 7
    out[:, 3] = d & 0xFF
    out[:, 4] = d >> 8
    return out.tobytes()


def _node_ok(rows: np.ndarray) -> np.ndarray:
    """Which 5-byte rows are well-formed nodes: exactly one of the two start bits set, the
    check bit set, the angle below a full turn."""
    b0 = rows[:, 0].astype(np.int64)
    b1 = rows[:, 1].astype(np.int64)
    angle = (b1 >> 1) | (rows[:, 2].astype(np.int64) << 7)
    return ((b0 & 1) != ((b0 >> 1) & 1)) & ((b1 & 1) == 1) & (angle < FULL_TURN_Q6)


def _decode_rows(rows: np.ndarray) -> Nodes:
    b0 = rows[:, 0].astype(np.int64)
    return Nodes(start=(b0 & 1).astype(bool), quality=(b0 >> 2).astype(np.uint8),
                 angle_q6=(rows[:, 1].astype(np.int64) >> 1) | (rows[:, 2].astype(np.int64) << 7),
                 distance_q2=rows[:, 3].astype(np.int64) | (rows[:, 4].astype(np.int64) << 8))


class ResponseParser:
    """The host's side: turns the device's bytes into answers (see the module docstring for
    how it resynchronises). Pure and never raises; counts what it had to skip."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._single: int | None = None     # answer type whose payload comes next
        self._stream: int | None = None     # answer type of the running stream
        self._locked = False
        self.bytes_skipped = 0
        self.capsules_ignored = 0

    def feed(self, data: bytes) -> list[Answer]:
        self._buf += data
        out: list[Answer] = []
        while self._step(out):
            pass
        return out

    def _step(self, out: list[Answer]) -> bool:
        """Consume what the head of the buffer holds; False when more bytes are needed."""
        buf = self._buf
        if not buf:
            return False
        if self._single is not None:
            return self._single_payload(out)
        if buf[0] == SYNC_BYTE and (len(buf) < 2 or buf[1] == SYNC_BYTE2):
            return self._descriptor(out)
        if self._stream == ANS_TYPE_MEASUREMENT:
            return self._nodes(out)
        if self._stream == ANS_TYPE_MEASUREMENT_CAPSULED and len(buf) >= CAPSULE_BYTES \
                and (buf[0] >> 4, buf[1] >> 4) == (0xA, 0x5):
            # Express capsules are recognised so they are not counted as noise, but this
            # project's driver asks for the standard scan only.
            self.capsules_ignored += 1
            del buf[:CAPSULE_BYTES]
            return True
        if self._stream == ANS_TYPE_MEASUREMENT_CAPSULED and len(buf) < CAPSULE_BYTES:
            return False
        self._skip(1)
        return True

    def _descriptor(self, out: list[Answer]) -> bool:
        buf = self._buf
        if len(buf) < DESCRIPTOR_BYTES:
            return False
        word = struct.unpack_from("<I", buf, 2)[0]
        length, mode, answer_type = word & 0x3FFFFFFF, word >> 30, buf[6]
        if ANSWERS.get(answer_type) != (length, mode):
            self._skip(1)                    # not a descriptor we know: noise
            return True
        del buf[:DESCRIPTOR_BYTES]
        self._locked = False
        if mode == SEND_MODE_MULTI:
            self._stream = answer_type
            out.append(StreamStarted(answer_type))
        else:
            self._stream = None              # a single answer ends any stream
            self._single = answer_type
        return True

    def _single_payload(self, out: list[Answer]) -> bool:
        answer_type = self._single
        length = ANSWERS[answer_type][0]
        if len(self._buf) < length:
            return False
        payload = bytes(self._buf[:length])
        self._single = None
        if answer_type == ANS_TYPE_DEVINFO:
            answer: Answer | None = DeviceInfo.decode(payload)
        elif answer_type == ANS_TYPE_DEVHEALTH:
            answer = Health.decode(payload)
        else:
            answer = SampleRate.decode(payload)
        if answer is None:
            return True                      # malformed: hunt again from the payload's first byte
        del self._buf[:length]
        out.append(answer)
        return True

    def _nodes(self, out: list[Answer]) -> bool:
        buf = self._buf
        if not self._locked:
            need = LOCK_NODES * NODE_BYTES
            if len(buf) < need:
                return False
            rows = np.frombuffer(bytes(buf[:need]), dtype=np.uint8).reshape(LOCK_NODES, NODE_BYTES)
            if not _node_ok(rows).all():
                self._skip(1)
                return True
            self._locked = True
        whole = len(buf) // NODE_BYTES
        cut = self._descriptor_within(whole * NODE_BYTES)
        if cut is not None:
            # A descriptor the noise put off the node grid: nodes end where it begins.
            whole = cut // NODE_BYTES
            if whole == 0:
                self._locked = False
                self._skip(cut)
                return True
        if whole == 0:
            return False
        rows = np.frombuffer(bytes(buf[: whole * NODE_BYTES]), dtype=np.uint8).reshape(whole, NODE_BYTES)
        ok = _node_ok(rows)
        good = whole if ok.all() else int(np.argmin(ok))
        if good:
            out.append(_decode_rows(rows[:good]))
            del buf[: good * NODE_BYTES]
        if good < whole:
            self._locked = False             # a bad node: resynchronise from here
        return good > 0 or not self._locked

    def _descriptor_within(self, end: int) -> int | None:
        """Where a whole, known descriptor starts in the first `end` bytes (after byte 0),
        or None. Seven bytes must match, so node data practically never fakes one."""
        pos = self._buf.find(bytes((SYNC_BYTE, SYNC_BYTE2)), 1, end + 1)
        while 0 < pos <= end:
            if pos + DESCRIPTOR_BYTES <= len(self._buf):
                word = struct.unpack_from("<I", self._buf, pos + 2)[0]
                if ANSWERS.get(self._buf[pos + 6]) == (word & 0x3FFFFFFF, word >> 30):
                    return pos
            pos = self._buf.find(bytes((SYNC_BYTE, SYNC_BYTE2)), pos + 1, end + 1)
        return None

    def _skip(self, n: int) -> None:
        del self._buf[:n]
        self.bytes_skipped += n

"""`lorascout inspect`: decode radio frames from a capture file or a live RN2483 modem.

    lorascout inspect run.capture.jsonl                 frames, records, statistics
    lorascout inspect run.capture.jsonl --summary       statistics only
    lorascout inspect run.capture.jsonl --json          the same for scripts
    lorascout inspect run.capture.jsonl --pcap out.pcap [--pcap-mode per-receiver]
    lorascout inspect --serial /dev/ttyUSB0 --profile eu868-g3 --count 20 --timeout 60
    lorascout inspect --write-dissector lorascout.lua   Wireshark dissector (generated)
    lorascout inspect --schema                          every dialect's record table as Markdown

Frames of every known record dialect (firmware.schemes.all_dialects(): the core plus each
scheme's) are decoded; each frame shows its dialect, each record its type.

Statistics are per transmitting node (`sender_stats`): frames, bytes, airtime and its share
of every duty-cycle window per sub-band, and, per receiver, frames received and frames lost
according to gaps in the originator's sequence numbers.
"""
from __future__ import annotations

import argparse
import bisect
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from typing import Any

from firmware.comms.codec import REASONS, Reason
from firmware.comms.frame import SEQ_MODULUS, decode_frame, seq_newer
from firmware.comms.link import RATE_WINDOW_US
from firmware.comms.schema import DialectSet, markdown_table
from firmware.schemes import all_dialects
from hal.lora import PROFILES, RadioProfile
from hal.samples import RadioRxFrame
from host_tools.options import JSON, Opt, add_options
from host_tools.safe_io import strict_dumps
from radio_sim.air_log import FATES, RECEIVED, AirFrame, Reception

UNKNOWN_SENDER = 255           # serial mode: sender of a frame whose header cannot be read
PEAK_WINDOW_US = RATE_WINDOW_US   # DESIGN.md: peak bytes/s over a sliding 10 s window, the cap's window

# ETSI EN 300 220-2 / ERC Rec 70-03 sub-bands: (low Hz, high Hz, name, duty cycle)
EU868_SUB_BANDS = (
    (863_000_000, 865_000_000, "g(K)", 0.001), (865_000_000, 868_000_000, "g(L)", 0.01),
    (868_000_000, 868_600_000, "g1", 0.01), (868_700_000, 869_200_000, "g2", 0.001),
    (869_400_000, 869_650_000, "g3", 0.10), (869_700_000, 870_000_000, "g4", 0.01),
)


class InspectError(RuntimeError):
    pass


def sub_band_for(freq_hz: int, profile: RadioProfile | None = None) -> tuple[str, float | None]:
    """(sub-band name, duty-cycle limit) of a frequency: the profile's own if it is on the
    profile's frequency (so names match LinkLayer's airtime counters), else the EU table."""
    if profile is not None and profile.freq_hz == freq_hz:
        return profile.sub_band, profile.duty_cycle
    for lo, hi, name, duty in EU868_SUB_BANDS:
        if lo <= freq_hz <= hi:
            return name, duty
    return f"{freq_hz / 1e6:.3f}MHz", None


def seq_gaps(seqs: Iterable[int]) -> int:
    """Frames missing from a series of sequence numbers in arrival order (RFC 1982):
    repeats and stragglers count nothing."""
    lost, last = 0, None
    for s in seqs:
        if last is None or seq_newer(s, last):
            if last is not None:
                lost += (s - last) % SEQ_MODULUS - 1
            last = s
    return lost


@dataclass
class SenderStats:
    sender_id: int
    frames: int = 0
    bytes: int = 0
    airtime_us: int = 0
    relayed_frames: int = 0                   # transmitted for another originator
    airtime_us_by_sub_band: dict[str, int] = field(default_factory=dict)
    duty_cycle_limit_by_sub_band: dict[str, float | None] = field(default_factory=dict)
    duty_cycle_max_by_sub_band: dict[str, float] = field(default_factory=dict)   # worst window
    reasons: dict[str, int] = field(default_factory=dict)    # decode reason of what it sent
    fates: dict[str, int] = field(default_factory=dict)      # what happened at the receivers
    seq_lost_on_air: int = 0                  # gaps in its own sequence numbers as transmitted
    rx_by_receiver: dict[int, dict[str, int]] = field(default_factory=dict)  # receiver -> received, lost
    duration_s: float = 0.0
    bytes_per_s: float = 0.0
    frames_per_s: float = 0.0
    peak_bytes_per_s_10s: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["rx_by_receiver"] = {str(k): v for k, v in self.rx_by_receiver.items()}
        return d


def _max_window_use(intervals: list[tuple[int, int]], window_us: int) -> int:
    """Largest airtime inside any window of length `window_us` (non-overlapping intervals in
    time order). The worst window ends at some frame end."""
    starts = [s for s, _ in intervals]
    ends = [e for _, e in intervals]
    prefix = [0]
    for s, e in intervals:
        prefix.append(prefix[-1] + e - s)
    best = 0
    for j, end in enumerate(ends):
        start = end - window_us
        i = bisect.bisect_right(ends, start)          # first interval ending after `start`
        use = prefix[j + 1] - prefix[i]
        if i <= j and starts[i] < start:
            use -= start - starts[i]
        best = max(best, use)
    return best


def sender_stats(frames: Iterable[AirFrame], profile: RadioProfile | None = None,
                 duration_us: int | None = None) -> dict[int, SenderStats]:
    """Per transmitting node statistics of an air log. With the profile the capture was made
    with, sub-band names and airtime agree with LinkLayer's counters (sent.frames, sent.bytes,
    airtime_us.<sub-band>). `duration_us` defaults to the span of the whole log."""
    frames = sorted(frames, key=lambda a: (a.start_us, a.sender_id))
    out: dict[int, SenderStats] = {}
    window_us = profile.duty_cycle_window_us if profile else 3_600_000_000
    intervals: dict[tuple[int, str], list[tuple[int, int]]] = {}
    own_seqs: dict[int, list[int]] = {}
    heard: dict[tuple[int, int], list[int]] = {}      # (originator, receiver) -> seqs in order
    starts: dict[int, list[tuple[int, int]]] = {}
    for a in frames:
        st = out.setdefault(a.sender_id, SenderStats(a.sender_id))
        airtime = a.end_us - a.start_us
        st.frames += 1
        st.bytes += len(a.payload)
        st.airtime_us += airtime
        sb, limit = sub_band_for(a.freq_hz, profile)
        st.airtime_us_by_sub_band[sb] = st.airtime_us_by_sub_band.get(sb, 0) + airtime
        st.duty_cycle_limit_by_sub_band[sb] = limit
        intervals.setdefault((a.sender_id, sb), []).append((a.start_us, a.end_us))
        starts.setdefault(a.sender_id, []).append((a.start_us, len(a.payload)))
        res = decode_frame(a.payload)
        st.reasons[res.reason.value] = st.reasons.get(res.reason.value, 0) + 1
        for r in a.receptions:
            st.fates[r.fate] = st.fates.get(r.fate, 0) + 1
        if res.frame is None:
            continue
        if res.frame.sender_id != a.sender_id:
            st.relayed_frames += 1
        else:
            own_seqs.setdefault(a.sender_id, []).append(res.frame.seq)
        for r in a.receptions:
            if r.fate == RECEIVED:
                heard.setdefault((res.frame.sender_id, r.receiver_id), []).append(res.frame.seq)
    span_us = duration_us if duration_us is not None else (
        max(a.end_us for a in frames) - min(a.start_us for a in frames) if frames else 0)
    span_s = max(span_us, 1) / 1e6
    for (sender, sb), iv in intervals.items():
        out[sender].duty_cycle_max_by_sub_band[sb] = _max_window_use(iv, window_us) / window_us
    for sender, seqs in own_seqs.items():
        out[sender].seq_lost_on_air = seq_gaps(seqs)
    for (origin, receiver), seqs in sorted(heard.items()):
        st = out.setdefault(origin, SenderStats(origin))
        st.rx_by_receiver[receiver] = {"received": len(set(seqs)), "lost": seq_gaps(seqs)}
    for sender, st in out.items():
        st.duration_s = span_s
        st.bytes_per_s = st.bytes / span_s
        st.frames_per_s = st.frames / span_s
        ss = starts.get(sender, [])
        t = [s for s, _ in ss]
        prefix = [0]
        for _, n in ss:
            prefix.append(prefix[-1] + n)
        peak = 0
        for i, t0 in enumerate(t):
            j = bisect.bisect_left(t, t0 + PEAK_WINDOW_US)
            peak = max(peak, prefix[j] - prefix[i])
        st.peak_bytes_per_s_10s = peak / (PEAK_WINDOW_US / 1e6)
    return dict(sorted(out.items()))


# ---- per-frame description -----------------------------------------------------------

def _unit_suffix(name: str, unit: str) -> str:
    """Show the unit only where the field name does not already carry it."""
    tail = name.rsplit("_", 1)[-1]
    return "" if tail in ("cm", "cdeg", "cmps", "dm", "id", "us", "m") or not unit else f" ({unit})"


def fingerprint_warnings(theirs: dict[str, int] | None, ours: DialectSet) -> list[str]:
    """What a capture's recorded dialect fingerprints mean for decoding it here: one line per
    dialect whose frames will be rejected (a dialect only we know costs nothing)."""
    if theirs is None:
        return []
    mine = ours.fingerprints()
    out = []
    for name, fp in theirs.items():
        if name not in mine:
            out.append(f"capture dialect {name!r} (fingerprint 0x{fp:04X}) is not one of ours; its frames will be "
                       f"rejected (unknown dialect, or a bad CRC if its id is one of ours)")
        elif fp != mine[name]:
            every = " (the core's: every frame)" if name == ours.core.name else ""
            out.append(f"capture dialect {name!r} fingerprint 0x{fp:04X} differs from ours 0x{mine[name]:04X}; "
                       f"its frames{every} will fail the CRC")
    return out


def describe(a: AirFrame, profile: RadioProfile | None = None) -> dict[str, Any]:
    dialects = all_dialects()
    res = decode_frame(a.payload, dialects)
    d: dict[str, Any] = {
        "start_us": a.start_us, "end_us": a.end_us, "tx_id": a.sender_id, "freq_hz": a.freq_hz,
        "sf": a.sf, "bw_hz": a.bw_hz, "size_bytes": len(a.payload), "airtime_us": a.end_us - a.start_us,
        "sub_band": sub_band_for(a.freq_hz, profile)[0], "reason": res.reason.value, "detail": res.detail,
        "payload_hex": a.payload.hex(),
        "receptions": [{"receiver_id": r.receiver_id, "rssi_dbm": r.rssi_dbm, "snr_db": r.snr_db,
                        "fate": r.fate} for r in a.receptions],
    }
    if res.frame is not None:
        f = res.frame
        d.update(sender_id=f.sender_id, seq=f.seq, hops_taken=f.hops_taken, hops_left=f.hops_left,
                 dialect_id=f.dialect_id, dialect=dialects.get(f.dialect_id).name,
                 records=[{"dialect": dialects.dialect_of(n).name, "type": n, "values": v} for n, v in f.records])
    return d


def format_frame(d: dict[str, Any]) -> str:
    head = (f"{d['start_us'] / 1e6:14.6f} s  tx {d['tx_id']:3d}  {d['size_bytes']:3d} B  "
            f"SF{d['sf']} BW{d['bw_hz'] // 1000} {d['freq_hz'] / 1e6:.3f} MHz  "
            f"airtime {d['airtime_us'] / 1e3:.3f} ms  ")
    if d["reason"] != Reason.OK.value:
        lines = [head + f"REJECTED {d['reason'].upper()}: {d['detail']}"]
    else:
        relay = "" if d["sender_id"] == d["tx_id"] else f" (relayed for {d['sender_id']})"
        lines = [head + f"ok  sender {d['sender_id']} seq {d['seq']} hops {d['hops_taken']}/{d['hops_left']}"
                        f"  dialect {d['dialect_id']} {d['dialect']}{relay}"]
        dialects = all_dialects()
        for rec in d["records"]:
            rt = dialects.record(rec["type"])
            vals = " ".join(f"{fl.name}={rec['values'][fl.name]}{_unit_suffix(fl.name, fl.unit)}" for fl in rt.fields)
            lines.append(f"      {rec['dialect'] + '.' + rec['type']:18s} {vals}")
    if d["receptions"]:
        lines.append("      rx      " + "  ".join(
            f"{r['receiver_id']}:{r['fate']} {r['rssi_dbm']:.1f} dBm {r['snr_db']:.1f} dB" for r in d["receptions"]))
    return "\n".join(lines)


def format_stats(stats: dict[int, SenderStats], reasons: Counter) -> str:
    lines = []
    span = next(iter(stats.values())).duration_s if stats else 0.0
    lines.append(f"per-sender statistics over {span:.3f} s")
    lines.append(f"{'sender':>6} {'frames':>7} {'bytes':>8} {'B/s':>8} {'peak B/s':>9} {'frames/s':>9} "
                 f"{'airtime s':>10} {'relayed':>7} {'seq lost':>8}  sub-band: worst 1 h duty cycle / limit")
    for s, st in stats.items():
        bands = ", ".join(
            f"{sb}: {st.duty_cycle_max_by_sub_band.get(sb, 0.0) * 100:.3f} % / "
            + ("none" if st.duty_cycle_limit_by_sub_band.get(sb) is None else f"{st.duty_cycle_limit_by_sub_band[sb] * 100:g} %")
            for sb in st.airtime_us_by_sub_band)
        lines.append(f"{s:>6} {st.frames:>7} {st.bytes:>8} {st.bytes_per_s:>8.2f} {st.peak_bytes_per_s_10s:>9.2f} "
                     f"{st.frames_per_s:>9.3f} {st.airtime_us / 1e6:>10.3f} {st.relayed_frames:>7} "
                     f"{st.seq_lost_on_air:>8}  {bands}")
    links = [(s, r, v) for s, st in stats.items() for r, v in st.rx_by_receiver.items()]
    if links:
        lines.append("reception by originator -> receiver (loss from sequence gaps)")
        for s, r, v in links:
            total = v["received"] + v["lost"]
            lines.append(f"  {s:>3} -> {r:<3} received {v['received']:>6}  lost {v['lost']:>6}"
                         f"  ({(v['lost'] / total * 100) if total else 0:.1f} %)")
    fates = Counter()
    for st in stats.values():
        fates.update(st.fates)
    if fates:
        lines.append("fates at receivers: " + ", ".join(f"{f}={fates[f]}" for f in FATES if fates[f]))
    lines.append("decode: " + ", ".join(f"{r.value}={reasons[r.value]}" for r in REASONS if reasons[r.value]))
    return "\n".join(lines)


# ---- live modem ----------------------------------------------------------------------

def serial_receive(url: str, profile: RadioProfile, on_frame: Callable[[AirFrame], None], *,
                   count: int | None = None, timeout_s: float | None = None, configure: bool = True,
                   receiver_id: int = 0) -> int:
    """Continuous receive on an RN2483-compatible modem through the project's driver
    (hal.rn2483.Rn2483Modem: it configures the profile unless `configure` is False, re-arms
    `radio rx 0` after every frame or `radio_err`, and asks each frame's rssi and snr). Each
    frame becomes an AirFrame stamped with the driver's clock (wall-clock microseconds since
    it opened the port). Returns the number of frames; stops at `count`, `timeout_s`, or
    KeyboardInterrupt."""
    from hal.rn2483 import Rn2483Error, Rn2483Modem

    try:
        modem = Rn2483Modem(url, profile, configure=configure)
    except Rn2483Error as e:
        raise InspectError(str(e)) from None
    t0 = time.monotonic()
    deadline = None if timeout_s is None else t0 + timeout_s
    m = profile.modulation
    n = 0
    try:
        while count is None or n < count:
            remaining_s = None if deadline is None else deadline - time.monotonic()
            if remaining_s is not None and remaining_s <= 0:
                break
            modem.wait(0.2 if remaining_s is None else min(0.2, remaining_s))
            try:
                events = modem.poll()
            except Rn2483Error as e:
                raise InspectError(str(e)) from None
            for e in events:
                if not isinstance(e, RadioRxFrame) or (count is not None and n >= count):
                    continue
                res = decode_frame(e.payload)
                sender = res.frame.sender_id if res.frame is not None else UNKNOWN_SENDER
                on_frame(AirFrame(e.stamp_us, e.stamp_us + profile.airtime_us(len(e.payload)), sender,
                                  profile.freq_hz, m.sf, m.bw_hz, e.payload,
                                  (Reception(receiver_id, e.rssi_dbm, e.snr_db, RECEIVED),)))
                n += 1
    finally:
        modem.close()          # leaves the module idle (`radio rxstop`)
    if modem.lines_ignored:
        print(f"warning: the modem sent {modem.lines_ignored} unreadable or unexpected line(s)", file=sys.stderr)
    return n


# ---- command -----------------------------------------------------------------------------

OPTIONS = (
    Opt("capture", "in_file", "capture file (JSON Lines, from `lorascout run --capture`)"),
    JSON,
    Opt("--summary", "flag", "statistics only, no per-frame lines"),
    Opt("--pcap", "out_file", "also write a LoRaTap pcap (LINKTYPE 270) for Wireshark", metavar="OUT"),
    Opt("--pcap-mode", "choice", "one packet per transmission (best RSSI) or per receiver that got it",
        choices=("per-frame", "per-receiver"), default="per-frame"),
    Opt("--serial", "text", "pyserial URL or device of an RN2483-compatible modem", metavar="PORT"),
    Opt("--profile", "choice", "radio profile to configure (serial; default eu868-g3) or to assume for a capture "
        "whose header names an unknown profile", choices=lambda: sorted(PROFILES)),
    Opt("--count", "int", "serial: stop after N frames", lo=1, hi=1_000_000_000, metavar="N"),
    Opt("--timeout", "float", "serial: stop after S seconds", unit="s", lo=0.0, lo_open=True, hi=1e7, metavar="S"),
    Opt("--no-configure", "flag", "serial: do not send `radio set` commands"),
    Opt("--receiver-id", "int", "serial: id recorded as the receiver", lo=0, hi=255, default=0, metavar="ID"),
    Opt("--write-capture", "out_file", "serial: save received frames as a capture", metavar="PATH"),
    Opt("--write-dissector", "out_file", "write the generated Wireshark Lua dissector", metavar="PATH"),
    Opt("--schema", "flag", "print every record dialect's table (id, fingerprint, records) as Markdown"),
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, OPTIONS)


def _report(frames: list[AirFrame], profile: RadioProfile | None, args: argparse.Namespace,
            header: dict[str, Any], printed: bool) -> None:
    stats = sender_stats(frames, profile)
    reasons = Counter(decode_frame(a.payload).reason.value for a in frames)
    if args.json:
        doc = {"header": header, "reasons": {r.value: reasons[r.value] for r in REASONS},
               "senders": {str(k): v.as_dict() for k, v in stats.items()}}
        if not args.summary:
            doc["frames"] = [describe(a, profile) for a in frames]
        print(strict_dumps(doc))
        return
    if not args.summary and not printed:
        for a in frames:
            print(format_frame(describe(a, profile)))
    print(format_stats(stats, reasons))


def main(args: argparse.Namespace) -> int:
    try:
        return _main(args)
    except BrokenPipeError:        # `lorascout inspect x | head` is fine
        sys.stderr.close()
        return 0
    except (InspectError, OSError, ValueError) as e:
        print(f"lorascout inspect: error: {e}", file=sys.stderr)
        return 1


def _main(args: argparse.Namespace) -> int:
    from host_tools.capture import CaptureWriter, read_capture_lines
    from host_tools.pcap import check_frame, write_pcap

    # Everything that can be refused is refused before anything is read or written.
    if args.capture and args.serial:
        raise InspectError("give a capture file or --serial, not both")
    if args.pcap and not (args.capture or args.serial):
        raise InspectError("--pcap needs a capture file or --serial")
    if args.write_capture and not args.serial:
        raise InspectError("--write-capture needs --serial")
    if not (args.capture or args.serial or args.write_dissector or args.schema):
        raise InspectError("nothing to do: give a capture file, --serial PORT, --write-dissector or --schema")
    if args.write_dissector:
        from host_tools.dissector.generate import generate_lua
        from host_tools.safe_io import write_text
        write_text(args.write_dissector, generate_lua())
        print(f"wrote Wireshark dissector {args.write_dissector}", file=sys.stderr)
    if args.schema:
        print(markdown_table())
    if args.capture:
        header, it = read_capture_lines(args.capture)
        numbered = list(it)
        frames = [a for _, a in numbered]
        if args.pcap:
            for line, a in numbered:
                try:
                    check_frame(a.start_us, a.freq_hz, a.bw_hz, a.sf)
                except ValueError as exc:
                    raise InspectError(f"{args.capture}:{line}: {exc}; no pcap written") from None
        profile = PROFILES.get(header.profile) or (PROFILES[args.profile] if args.profile else None)
        for warning in fingerprint_warnings(header.fingerprints, all_dialects()):
            print(f"warning: {warning}", file=sys.stderr)
        hdr = {"capture": str(args.capture), "profile": header.profile, "frames": len(frames),
               "fingerprints": {n: f"0x{fp:04X}" for n, fp in all_dialects().fingerprints().items()},
               "meta": header.meta}
        if not args.json:
            print(f"capture {args.capture}: profile {header.profile}, {len(frames)} frames")
        _report(frames, profile, args, hdr, printed=False)
    elif args.serial:
        profile = PROFILES[args.profile or "eu868-g3"]
        frames: list[AirFrame] = []
        live = not args.json and not args.summary
        writer = CaptureWriter(args.write_capture, profile.name, {"source": args.serial}) if args.write_capture \
            else None

        def on_frame(a: AirFrame) -> None:
            frames.append(a)
            if writer:
                writer.write(a)
            if live:
                print(format_frame(describe(a, profile)), flush=True)

        ended = False
        try:
            serial_receive(args.serial, profile, on_frame, count=args.count, timeout_s=args.timeout,
                           configure=not args.no_configure, receiver_id=args.receiver_id)
            ended = True
        except KeyboardInterrupt:
            ended = True
        finally:
            if writer:
                # What was received is kept, even when the modem failed later; a session that
                # failed before any frame leaves an earlier capture at that path as it was.
                if ended or frames:
                    writer.close()
                else:
                    writer.abort()
        _report(frames, profile, args, {"serial": args.serial, "profile": profile.name, "frames": len(frames)},
                printed=live)
    if args.pcap:
        n = write_pcap(args.pcap, frames, args.pcap_mode)
        print(f"wrote {n} packets to {args.pcap} ({args.pcap_mode})", file=sys.stderr)
    return 0

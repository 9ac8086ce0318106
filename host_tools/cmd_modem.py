"""`lorascout modem`: serve N virtual RN2483 modems on pseudo-terminals, on one channel,
in wall-clock time, until SIGINT or SIGTERM. Prints each device path on its own line."""
from __future__ import annotations

import argparse
import signal
import sys
import time

from hal.lora import PROFILES, profile as radio_profile
from host_tools.options import SEED_MAX, Opt, add_options

# With no occupancy map every modem is in range of every other; they stand a few metres
# apart on a line so received powers differ the way they would on a bench.
_SPACING_M = 2.0


OPTIONS = (
    Opt("--count", "int", "number of modems", unit="modems", lo=1, hi=64, default=2),
    Opt("--radio", "choice", "radio profile the channel carries", choices=lambda: sorted(PROFILES),
        default="eu868-g3"),
    Opt("--seed", "int", "channel random seed", lo=0, hi=SEED_MAX, default=0),
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_options(parser, OPTIONS)


def main(args: argparse.Namespace) -> int:
    from radio_sim.channel import Channel
    from radio_sim.rn2483 import on_air_settings
    from radio_sim.virtual_modem import ModemBank

    prof = radio_profile(args.radio)
    try:
        on_air_settings(prof)
    except ValueError as e:
        print(f"lorascout modem: --radio {args.radio}: {e}", file=sys.stderr)
        return 2
    channel = Channel(prof, args.seed)
    for node_id in range(args.count):
        channel.attach(node_id, lambda x_m=node_id * _SPACING_M: (x_m, 0.0))

    t0_ns = time.monotonic_ns()

    def now_us() -> int:
        return (time.monotonic_ns() - t0_ns) // 1000

    stop = False
    with ModemBank(channel, prof, list(range(args.count)), lockstep=False) as bank:
        def on_signal(signum, frame):
            nonlocal stop
            stop = True
            bank.wake()

        signal.signal(signal.SIGINT, on_signal)
        signal.signal(signal.SIGTERM, on_signal)
        for path in bank.paths:
            print(path)
        sys.stdout.flush()
        bank.serve(now_us, lambda: stop)
    return 0

"""`lorascout` command line: one sub-command per module, imported only when used."""
from __future__ import annotations

import argparse
import importlib
import sys

EXIT_INTERRUPTED = 130

# name -> (module, one-line help). Each module defines add_arguments(parser) and main(args) -> int.
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("host_tools.cmd_run", "run one mission on the simulated HAL and report it"),
    "bench": ("host_tools.cmd_bench", "measure firmware tick time, simulation speed and memory"),
    "modem": ("host_tools.cmd_modem", "serve virtual RN2483 modems on pseudo-terminals"),
    "inspect": ("host_tools.cmd_inspect", "decode radio frames from a serial port or a capture"),
    "sweep": ("host_tools.cmd_sweep", "run maps x strategies x seeds and tabulate p_max and bandwidth"),
    "map": ("host_tools.cmd_map", "the area a map asks a team to cover, and how much of it a planner can see at all"),
    "robot": ("host_tools.cmd_robot", "run one robot's firmware in real time on the peripherals a configuration file names"),
    "hil": ("host_tools.cmd_hil", "hardware in the loop: lorascout robot processes on a real-time world's emulated devices"),
}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        argv = ["run"]  # the built-in default mission
    parser = argparse.ArgumentParser(prog="lorascout", description="lorascout: low-bandwidth multi-robot exploration")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (module_name, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(_module=module_name)
        if argv[0] == name:
            importlib.import_module(module_name).add_arguments(p)
    args = parser.parse_args(argv)     # every option is checked here (host_tools/options.py): exit 2
    try:
        return int(importlib.import_module(args._module).main(args) or 0)
    except KeyboardInterrupt:
        # Commands that can stop cleanly on Ctrl-C do (run, sweep); anything else ends here,
        # without a traceback, with the status a shell gives a command SIGINT ended.
        print(f"lorascout {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())

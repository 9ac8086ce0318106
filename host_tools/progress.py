"""Progress on stderr for long work: a bar when stderr is a terminal, a line now and then
when it is not; neither with --quiet."""
from __future__ import annotations

import sys
import time

from tqdm import tqdm


def progress_bar(total: float, desc: str, unit: str, quiet: bool) -> tqdm:
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                disable=quiet or not sys.stderr.isatty(), dynamic_ncols=True)


# Without a terminal (a log file, nohup, CI) a bar shows nothing: a line this often instead.
LINE_EVERY_S = 60.0


class ProgressLines:
    """For long work whose stderr is not a terminal: a line on stderr every LINE_EVERY_S
    seconds of wall time (none with quiet, or on a terminal, where the bar is)."""

    def __init__(self, prefix: str, quiet: bool) -> None:
        self.prefix = prefix
        self.on = not quiet and not sys.stderr.isatty()
        self._next = time.monotonic() + LINE_EVERY_S

    def __call__(self, text: str) -> None:
        if self.on and time.monotonic() >= self._next:
            print(f"{self.prefix}: {text}", file=sys.stderr, flush=True)
            self._next = time.monotonic() + LINE_EVERY_S

"""Progress bars on stderr for long work: on only when stderr is a terminal and not --quiet."""
from __future__ import annotations

import sys

from tqdm import tqdm


def progress_bar(total: float, desc: str, unit: str, quiet: bool) -> tqdm:
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                disable=quiet or not sys.stderr.isatty(), dynamic_ncols=True)

"""What runs on a laptop: mission runner, CLI, sweeps, inspector, plots, benchmarks.

The firmware's numba kernels run on one thread here unless NUMBA_NUM_THREADS says
otherwise. A host runs many missions at once (a sweep's workers, a test suite, other work
on a shared machine), and there numba's spinning worker threads cost far more than the
second core gains: one 300 s team mission took 114 to 271 s with its default threads next
to other work, against 38 to 42 s on one thread, while on an idle machine the second
thread gains 8 to 20 %. Set before numba is imported, which reads it once."""
import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

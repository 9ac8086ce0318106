"""What runs on a laptop: mission runner, CLI, sweeps, inspector, plots, benchmarks.

The firmware's numba kernels run on one thread here unless NUMBA_NUM_THREADS says
otherwise. A host runs many missions at once (a sweep's workers, a test suite, other work
on a shared machine), and there numba's second thread costs far more than it gains: a
three-robot mission took 3.7 times the CPU and 2.7 times the wall time on two threads as on
one, next to other work (README, "Firmware speed"). Set before numba is imported, which
reads it once."""
import os

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

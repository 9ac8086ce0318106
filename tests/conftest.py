import os
from pathlib import Path

# The host tools run numba on one thread unless told otherwise (host_tools/__init__.py); the
# tests want at least two, so that the parallel kernels' thread-count tests compare something.
os.environ.setdefault("NUMBA_NUM_THREADS", str(max(2, os.cpu_count() or 1)))

import pytest  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
SHARED_MAPS = REPO.parent / "shared" / "maps"


@pytest.fixture(scope="session")
def shared_maps() -> Path:
    if not (SHARED_MAPS / "depot.yaml").exists():
        pytest.skip(f"the shared maps are not beside the repository ({SHARED_MAPS})")
    return SHARED_MAPS

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
SHARED_MAPS = REPO.parent / "shared" / "maps"


@pytest.fixture(scope="session")
def shared_maps() -> Path:
    if not (SHARED_MAPS / "depot.yaml").exists():
        pytest.skip(f"the shared maps are not beside the repository ({SHARED_MAPS})")
    return SHARED_MAPS

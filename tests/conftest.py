import os
import signal
from pathlib import Path

# The host tools run numba on one thread unless told otherwise (host_tools/__init__.py). The
# pool here has at least two, so that the parallel kernels' thread-count tests compare
# something, but the tests run on one (numba.set_num_threads is per calling thread): `make
# test` runs two test processes, and two threads each would crowd two cores.
os.environ.setdefault("NUMBA_NUM_THREADS", str(max(2, os.cpu_count() or 1)))

import numba  # noqa: E402
import pytest  # noqa: E402

numba.set_num_threads(1)

REPO = Path(__file__).resolve().parent.parent
SHARED_MAPS = REPO.parent / "shared" / "maps"


@pytest.fixture(scope="session")
def shared_maps() -> Path:
    if not (SHARED_MAPS / "depot.yaml").exists():
        pytest.skip(f"the shared maps are not beside the repository ({SHARED_MAPS})")
    return SHARED_MAPS


def pytest_addoption(parser):
    parser.addoption("--slow", action="store_true", default=False,
                     help="also run the tests marked slow (the decoder fuzz of 10^6 frames)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--slow"):
        return
    skip = pytest.mark.skip(reason="slow: run with --slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


class CliResult:
    """What one `lorascout` command did: exit status, stdout, stderr."""

    def __init__(self, code: int, out: str, err: str) -> None:
        self.code, self.out, self.err = code, out, err

    def __repr__(self) -> str:
        return f"CliResult(code={self.code}, out={self.out[-500:]!r}, err={self.err[-500:]!r})"


@pytest.fixture
def cli(capsys):
    """Run `lorascout ARGV...` in this process through its main function, as the shell would:
    argparse's exit (status 2) is caught and returned like any other status."""
    from host_tools.cli import main

    def run(*argv: str) -> CliResult:
        capsys.readouterr()
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        out, err = capsys.readouterr()
        return CliResult(code, out, err)

    return run


def tree_state(root: Path) -> dict[str, bytes | None]:
    """Every file under `root` with its bytes (folders as None): to prove nothing changed."""
    state: dict[str, bytes | None] = {}
    for p in sorted(root.rglob("*")):
        state[str(p.relative_to(root))] = p.read_bytes() if p.is_file() else None
    return state


@pytest.fixture
def sigint_as_in_a_terminal():
    """Ctrl-C delivered as under a terminal (Python's KeyboardInterrupt handler), even when
    the test run itself was started with SIGINT ignored (in the background, by some CI
    runners); the handler before the test is put back after it."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)

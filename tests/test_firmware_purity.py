"""firmware/ is pure: it reads no clock, draws no global randomness, does no I/O, and never
reaches into the simulator or host tools. Proven by reading its syntax trees."""
import ast
from pathlib import Path

FIRMWARE = Path(__file__).resolve().parent.parent / "firmware"
ALLOWED_ROOTS = {"firmware", "numpy", "numba", "crcmod", "math", "heapq", "dataclasses",
                 "typing", "__future__", "enum", "functools", "itertools", "collections", "struct",
                 "bisect", "hashlib", "zlib", "fractions", "abc",
                 "importlib"}   # the scheme registry imports only the scheme asked for
# scipy's pure computation only (DESIGN.md: ndimage, sparse.csgraph, spatial).
ALLOWED_SCIPY = {"scipy.ndimage", "scipy.sparse", "scipy.sparse.csgraph", "scipy.spatial"}
ALLOWED_HAL = {"hal.bundle", "hal.interfaces", "hal.samples", "hal.lora"}
FORBIDDEN_CALLS = {"open", "print", "input", "exec", "eval", "__import__"}
FORBIDDEN_ATTRS = {("np", "random"), ("numpy", "random")}


def _imports(tree: ast.AST):
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            yield node.lineno, ("." * node.level) + (node.module or "")


def _violations(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    bad = []
    for line, name in _imports(tree):
        root = name.split(".")[0]
        if name.startswith("."):
            continue  # relative: inside firmware
        if root == "scipy":
            if name not in ALLOWED_SCIPY:
                bad.append(f"{path.name}:{line}: imports {name} (only {', '.join(sorted(ALLOWED_SCIPY))})")
        elif root == "hal":
            if name not in ALLOWED_HAL:
                bad.append(f"{path.name}:{line}: imports {name} (only HAL interfaces and sample types)")
        elif root not in ALLOWED_ROOTS:
            bad.append(f"{path.name}:{line}: imports {name}")
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FORBIDDEN_CALLS:
            bad.append(f"{path.name}:{node.lineno}: calls {node.func.id}()")
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and (node.value.id, node.attr) in FORBIDDEN_ATTRS:
            bad.append(f"{path.name}:{node.lineno}: uses {node.value.id}.{node.attr} (global randomness)")
    return bad


def test_firmware_is_pure():
    files = sorted(FIRMWARE.rglob("*.py"))
    assert len(files) >= 8
    bad = [v for f in files for v in _violations(f)]
    assert bad == []


def test_the_checker_catches_what_it_must(tmp_path):
    sample = tmp_path / "bad.py"
    sample.write_text("import time\nfrom radio_sim import channel\nimport numpy as np\nx = np.random.rand()\n"
                      "from hal.sim import lidar\nprint(1)\nopen('f')\nimport threading\nimport scipy.io\n"
                      "from host_tools import cli\n")
    found = "\n".join(_violations(sample))
    for what in ("imports time", "imports radio_sim", "np.random", "hal.sim", "print()", "open()", "imports threading",
                 "imports scipy.io", "imports host_tools"):
        assert what in found


def test_no_scheme_imports_another():
    """firmware/schemes/X never imports firmware.schemes.Y: schemes compose through the
    registry (firmware.schemes.build), so each can be added, changed or removed alone."""
    schemes = FIRMWARE / "schemes"
    packages = sorted(p.name for p in schemes.iterdir() if p.is_dir() and (p / "__init__.py").exists())
    assert {"bayer_faigl", "dense_baseline", "independent"} <= set(packages)
    bad = []
    for package in packages:
        for f in sorted((schemes / package).rglob("*.py")):
            for line, name in _imports(ast.parse(f.read_text())):
                parts = name.split(".")
                if parts[:2] == ["firmware", "schemes"] and len(parts) > 2 and parts[2] in packages \
                        and parts[2] != package:
                    bad.append(f"{package}/{f.name}:{line}: imports {name}")
    assert bad == []

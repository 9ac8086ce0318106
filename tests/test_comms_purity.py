"""firmware/comms imports only what the brief allows: itself, crcmod, numpy, hal.lora,
hal.samples, hal.interfaces and the standard library's pure modules. The one exception is
the scheme registry (firmware.schemes), for the default set of dialects: imported inside a
function only, never at module level, because the schemes' dialects import comms."""
import ast
import pathlib

ALLOWED_PREFIXES = ("firmware.comms", "crcmod", "numpy", "hal.lora", "hal.samples", "hal.interfaces",
                    "__future__", "collections", "dataclasses", "enum", "fractions", "functools", "math", "typing")
LAZY_ONLY = "firmware.schemes"      # exactly the registry module, never a scheme package
ROOT = pathlib.Path(__file__).resolve().parents[1] / "firmware" / "comms"


def _violations(path: pathlib.Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    in_function = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                   for n in ast.walk(f)}
    bad = []
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        for n in names:
            if n == LAZY_ONLY and id(node) in in_function:
                continue
            if not any(n == p or n.startswith(p + ".") for p in ALLOWED_PREFIXES):
                bad.append(f"{path.name}:{node.lineno}: {n}")
    return bad


def test_comms_imports_are_pure():
    bad = [v for path in sorted(ROOT.glob("*.py")) for v in _violations(path)]
    assert not bad, bad


def test_the_checker_catches_a_scheme_imported_at_module_level(tmp_path):
    sample = tmp_path / "bad.py"
    sample.write_text("from firmware.schemes import all_dialects\nimport time\n"
                      "def f():\n    from firmware.schemes import all_dialects\n"
                      "    from firmware.schemes.bayer_faigl import records\n")
    assert _violations(sample) == ["bad.py:1: firmware.schemes", "bad.py:2: time",
                                   "bad.py:5: firmware.schemes.bayer_faigl"]

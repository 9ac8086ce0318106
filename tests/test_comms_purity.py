"""firmware/comms imports only what the brief allows: itself, crcmod, numpy, hal.lora,
hal.samples, hal.interfaces and the standard library's pure modules."""
import ast
import pathlib

ALLOWED_PREFIXES = ("firmware.comms", "crcmod", "numpy", "hal.lora", "hal.samples", "hal.interfaces",
                    "__future__", "collections", "dataclasses", "enum", "fractions", "math", "typing")


def test_comms_imports_are_pure():
    root = pathlib.Path(__file__).resolve().parents[1] / "firmware" / "comms"
    bad = []
    for path in sorted(root.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            for n in names:
                if not any(n == p or n.startswith(p + ".") for p in ALLOWED_PREFIXES):
                    bad.append(f"{path.name}:{node.lineno}: {n}")
    assert not bad, bad

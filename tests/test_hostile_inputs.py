"""Careless input never costs a result (issue 27). A table of bad values, generated per
option from the options' declarations (host_tools/options.py and each command's OPTIONS),
runs every command of the CLI: each ends with a non-zero status, no traceback, a message
naming the option (and, for numbers, the valid range), and every file that was there before
is unchanged."""
import importlib
import socket

import pytest

from host_tools.cli import COMMANDS
from tests.conftest import tree_state

GRID_LINE = '{"map_spec": "cave:4:40x40", "strategy": "minpos", "radio": "ideal-100Bps", "seed": 0, "robots": 2, ' \
            '"max_sim_s": 20.0}\n'


@pytest.fixture
def world(tmp_path):
    """Files a careless user points commands at: a file, a folder with a file in it, and a
    sweep's earlier grid; all must come through unchanged."""
    (tmp_path / "file").write_text("precious\n")
    (tmp_path / "dir").mkdir()
    (tmp_path / "dir" / "keep.txt").write_text("keep\n")
    (tmp_path / "grid").mkdir()
    (tmp_path / "grid" / "trials.partial.jsonl").write_text(GRID_LINE * 3)
    (tmp_path / "grid" / "tables.json").write_text("{}\n")
    (tmp_path / "huge.yaml").write_text("image: x.png\nresolution: 1e-9\norigin: [0, 0, 0]\nnegate: 0\n"
                                        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return tmp_path


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def bad_values(opt, root) -> list[str]:
    """Hostile values for one declared option: by kind, and around its declared range."""
    k = opt.kind
    if k in ("int", "float"):
        out = ["abc", "", "nan", "inf", "-inf", "1e308", "-1e308"]
        if k == "int":
            out += ["1.5", "1e3"]
        if opt.lo is not None:
            out.append(str(opt.lo) if opt.lo_open else str(opt.lo - 1 if k == "int" else opt.lo - 1e-3))
            out.append("-5")
        if opt.hi is not None:
            out.append(str(int(opt.hi) + 1) if k == "int" else repr(opt.hi * 1.001 + 1))
        return [v for v in out if not (v == "-5" and opt.lo is not None and opt.lo <= -5)]
    if k == "choice":
        return ["no-such-thing", ""]
    if k == "scheme":
        return ["no-such-scheme", "bayer-faigl:no-such-variant", "independent:x", ""]
    if k == "out_dir":
        return [str(root / "file"), str(root / "file" / "sub"), "/proc/lorascout-nope/out", ""]
    if k == "out_file":
        return [str(root / "dir"), str(root / "file" / "sub.out"), "/proc/lorascout-nope.out", "/dev/null", ""]
    if k == "in_file":
        return [str(root / "missing.jsonl"), str(root / "dir")]
    if k == "map":
        return ["nope", "cave:-1", "cave:1:5x5", "cave:99999999999", str(root / "missing.yaml"),
                str(root / "huge.yaml"), ""]
    if k == "pose":
        return ["a,b", "nan,1", "1,inf", "1e308,1", "1", ""]
    if k == "override":
        return ["x", "nope=1", "resolution_m=0", "resolution_m=1e-4", "logodds_min=5", "info_rays=1.5",
                "d_cam_m=nan", "presence_holds_target=maybe"]
    if k == "address":
        return [f"127.0.0.1:{_closed_port()}", "bad host!:1", "127.0.0.1:99999", ""]
    if k == "robot_at":
        return ["1", "a@5", "1@x", "-1@5", "64@5", "1@-1", "1@nan", "1@1e9", "@", "", "1@0%", "1@101%", "1@x%", "1%"]
    if k == "robot_share":
        return ["1", "a=0.5", "1=x", "-1=0.5", "64=0.5", "1=0", "1=1.5", "1=nan", "=", ""]
    if k == "text":
        return [""]
    assert k == "flag", k
    return []


def base_argv(command: str, root) -> list[str]:
    """Arguments that make each command valid and cheap apart from the value under test."""
    return {"sweep": ["--maps", "cave:4:40x40", "--out", str(root / "grid"), "--resume"],
            "inspect": ["--schema"]}.get(command, [])


def cases():
    for command, (module_name, _) in COMMANDS.items():
        for opt in importlib.import_module(module_name).OPTIONS:
            if opt.kind != "flag":
                yield pytest.param(command, opt, id=f"{command}-{opt.flag.lstrip('-')}")


def _argv(command, opt, value, root):
    base = base_argv(command, root)
    if opt.flag == "--out" and command == "sweep":
        base = ["--maps", "cave:4:40x40", "--resume"]
    if opt.flag == "--maps":
        base = ["--out", str(root / "grid"), "--resume"]
    return [command, *base, value] if opt.positional else [command, *base, f"{opt.flag}={value}"]


@pytest.mark.parametrize("command, opt", list(cases()))
def test_every_bad_value_of_every_option_is_refused_cleanly(command, opt, world, cli):
    values = bad_values(opt, world)
    assert values, f"no hostile values generated for {command} {opt.flag} ({opt.kind})"
    before = tree_state(world)
    for value in values:
        r = cli(*_argv(command, opt, value, world))
        said = f"{command} {opt.flag}={value!r}: {r}"
        assert r.code != 0, said
        assert "Traceback" not in r.err, said
        assert f"argument {opt.flag}" in r.err or opt.flag in r.err, said
        if opt.kind in ("int", "float") and value:
            assert opt.range_text() in r.err, said
        assert tree_state(world) == before, said


def test_the_table_covers_every_option_of_every_command(tmp_path):
    """A new option gets its hostile values from its kind; an unknown kind fails here."""
    from host_tools.options import KINDS, Opt

    for kind in KINDS:
        if kind != "flag":
            assert bad_values(Opt("--x", kind, "x", lo=0, hi=10), tmp_path), kind
    assert sum(1 for _ in cases()) >= 40


def test_numbers_from_the_issue_name_option_value_and_range(cli):
    for argv, says in [
        (["run", "--max-sim-s", "0"], "argument --max-sim-s: '0' is out of range; valid: 1 <= S <= 86400 s"),
        (["run", "--max-sim-s", "1e308"], "'1e308' is out of range"),
        (["run", "--robots", "300"], "argument --robots: '300' is out of range; valid: 1 <= N <= 64 robots"),
        (["bench", "--sim-s", "-5"], "argument --sim-s: '-5' is out of range; valid: 1 <= S <= 86400 s"),
        (["map", "--stride-m", "inf"], "argument --stride-m: 'inf' is not a finite number"),
        (["modem", "--seed", "-1"], "argument --seed: '-1' is out of range; valid: 0 <= N <= 4294967295"),
        (["inspect", "--serial", "loop://", "--timeout", "nan"], "argument --timeout: 'nan' is not a finite number"),
        (["inspect", "--serial", "loop://", "--receiver-id", "300"], "valid: 0 <= ID <= 255"),
        (["run", "--set", "resolution_m=0"], "resolution_m = 0.0 is outside the valid range 0.02 <= resolution_m"),
        (["run", "--set", "logodds_min=-0.1"], "logodds_min = -0.1 must be below logodds_free = -0.3"),
    ]:
        r = cli(*argv)
        assert r.code == 2 and says in r.err, (argv, r)


def test_a_bad_value_for_the_sweep_leaves_an_earlier_grid_alone(world, cli):
    """The defect: a sweep without --resume emptied the earlier grid's trials file first."""
    before = tree_state(world)
    r = cli("sweep", "--maps", "cave:4:40x40", "--out", world / "grid")
    assert r.code == 2
    assert "already holds a grid (3 trials in" in r.err and "--resume" in r.err and "--overwrite" in r.err
    r = cli("sweep", "--maps", "cave:4:40x40", "tpyo:1", "--out", world / "grid", "--resume")
    assert r.code == 2 and "argument --maps: unrecognised map spec 'tpyo:1'" in r.err
    r = cli("sweep", "--maps", "cave:4:40x40", "--out", world / "grid", "--resume", "--overwrite")
    assert r.code == 2 and "give one of them" in r.err
    assert tree_state(world) == before


def test_the_map_bounds_name_file_and_field(world, cli):
    r = cli("map", "--map", world / "huge.yaml")
    assert r.code == 2
    assert "huge.yaml:2: field 'resolution': 1e-09 m per cell is outside 0.01..1 m" in r.err

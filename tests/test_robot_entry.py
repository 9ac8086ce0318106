"""`lorascout robot --config robot.toml` (issue 26, item 1): a robot's HAL built from a
configuration file through the backend registry, every mistake in the file named (file,
table, key) before a device is opened, the firmware ticked on the wall clock with every
task's overruns counted against its budget, and SIGINT or SIGTERM ending the run with the
drive at zero and every device closed."""
import dataclasses
import itertools
import json
import logging
import math
import signal
import time
from pathlib import Path

import can
import numpy as np
import pytest
import serial

from firmware.agent import ExplorerAgent
from firmware.comms.frame import decode_frame
from firmware.scheduler import Task
from hal.config import BuildContext, Setting
from hal.lora import PROFILES
from hal.monotonic_clock import MonotonicClock
from hal.odrive_can import AXIS_STATE_CLOSED_LOOP_CONTROL, AXIS_STATE_IDLE, DiffDriveGeometry
from hal.registry import BACKENDS, backend_class, build_backend, check_backend
from host_tools.robot_config import (RESOURCE_TABLES, DeviceError, config_help, load_robot_config,
                                     open_robot)
from host_tools.robot_loop import SIGN_OFF_FRAMES, RobotLoop, next_tick
from tests.doubles import FakeAxes, FakeRadio, ManualWallClock, RobotProcess, ScriptedHal, ScriptedSlowTask

REPO = Path(__file__).resolve().parents[1]
SIM_EXAMPLE = REPO / "examples" / "robot-sim.toml"
REAL_EXAMPLE = REPO / "examples" / "robot-real.toml"
_channels = itertools.count()

# A small valid robot: every peripheral simulated, no radio (the scheme needs none).
SIM = {"robot": {"id": 0, "scheme": "independent"}, "world": {"map": "cave:1:20x20"},
       "lidar": {"backend": "sim"}, "odometry": {"backend": "sim"}, "drive": {"backend": "sim"}}
ODRIVE = {"backend": "odrive-can", "interface": "virtual", "channel": "odrive-config", "left_node": 0,
          "right_node": 1, "wheel_radius_m": 0.08, "track_width_m": 0.4}
DRIVE = {**ODRIVE, "max_v_mps": 0.8, "max_omega_radps": 1.5, "robot_radius_m": 0.25}


def toml_text(tables: dict) -> str:
    """Tables of strings, numbers and booleans as TOML."""
    def value(v):
        if isinstance(v, bool) or (isinstance(v, float) and not math.isfinite(v)):
            return str(v).lower()           # true, nan, inf
        return json.dumps(v)

    return "".join(f"[{name}]\n" + "".join(f"{k} = {value(v)}\n" for k, v in table.items()) + "\n"
                   for name, table in tables.items())


def changed(base: dict, changes: dict) -> dict:
    """`base` with tables' keys changed; a None table or key is left out."""
    out = {name: dict(table) for name, table in base.items()}
    for name, table in changes.items():
        if table is None:
            out.pop(name, None)
            continue
        merged = {**out.get(name, {}), **table}
        out[name] = {k: v for k, v in merged.items() if v is not None}
    return out


def write(tmp_path: Path, tables_or_text) -> Path:
    path = tmp_path / "robot.toml"
    path.write_text(tables_or_text if isinstance(tables_or_text, str) else toml_text(tables_or_text))
    return path


# ---- the configuration file: every kind of mistake named, before anything is opened --------

MISTAKES = [
    ({"robto": {"id": 0}}, "[robto]: unknown table; known: robot, params, world, clock, lidar"),
    ({"robot": None}, "[robot]: missing table"),
    ({"robot": {"id": None}}, "[robot] id: missing: this robot's id"),
    ({"robot": {"id": "zero"}}, "[robot] id: expected an integer, 0 <= X <= 63, got 'zero' (a string)"),
    ({"robot": {"id": 2, "team_size": 2}}, "[robot] id: 2 is not below team_size = 2"),
    ({"robot": {"team_size": 0}}, "[robot] team_size: 0 is out of range; valid: an integer, 1 <= X <= 64 robots"),
    ({"robot": {"scheme": "bayer-faigl:fastest"}}, "[robot] scheme: "),
    ({"robot": {"colour": "red"}}, "[robot] colour: unknown setting; this table takes id, team_size, scheme"),
    ({"robot": {"radio_profile": "eu433"}}, "[robot] radio_profile: 'eu433' is not one of 'eu868-g1'"),
    ({"drive": {"backend": "tank"}}, "[drive] backend: 'tank' is no drive backend; known: 'sim', 'odrive-can'"),
    ({"lidar": {"backend": None}}, "[lidar] backend: missing: which lidar this is, one of 'sim'"),
    ({"lidar": None}, "[lidar]: missing table: every robot has a lidar"),
    ({"odometry": {"fram": "own"}}, "[odometry] fram: unknown setting; backend 'sim' takes frame"),
    ({"odometry": {"frame": "mine"}}, "[odometry] frame: 'mine' is not one of 'shared', 'own'"),
    ({"world": None}, "[lidar] backend: 'sim' needs a [world] table"),
    ({"world": {"map": "cave:x"}}, "[world] map: "),
    ({"world": {"mapp": "cave:1"}}, "[world] mapp: unknown setting; this table takes map, seed"),
    ({"world": {"start_x_m": 1.0}}, "[world] start_y_m: missing: start_x_m is given"),
    ({"world": {"seed": 1.5}}, "[world] seed: expected an integer"),
    ({"world": {"start_x_m": 0.0, "start_y_m": 0.0}}, "[world] start_x_m: (0, 0) m is not on a free cell of map 'cave"),
    ({"params": {"speed_mps": 2}}, "[params] speed_mps: the explorer has no parameter 'speed_mps'"),
    ({"params": {"info_rays": 1.5}}, "[params] info_rays: info_rays = 1.5: takes a int"),
    ({"params": {"d_cam_m": "far"}}, "[params] d_cam_m: d_cam_m = 'far': takes a float"),
    ({"params": {"resolution_m": 0.0}}, "[params] resolution_m: resolution_m = 0.0 is outside the valid range"),
    ({"params": {"logodds_min": -0.1}}, "[params] logodds_min = -0.1 must be below logodds_free = -0.3"),
    ({"params": {"wiserx.tau_enabled": 1}}, "[params] wiserx.tau_enabled = 1: takes true or false"),
    ({"params": {"wiserx.kappa1": 5.0}}, "[params] wiserx.kappa1: scheme 'wiserx' has no parameter 'kappa1'"),
    ({"params": {"bayer-faigl.x": 1}}, "[params] bayer-faigl: scheme 'bayer-faigl' has no parameters of its own"),
    ({"params": {"wiserx.tau_enabled": False}},
     "[params] wiserx.tau_enabled=false: no scheme of this run is 'wiserx' ([robot] scheme = independent)"),
    ({"robot": {"scheme": "bayer-faigl:minpos"}}, "[robot] scheme: bayer-faigl:minpos needs radio"),
    ({"robot": {"scheme": "divide"}}, "[robot] scheme: divide needs floor_plan (the deployment's boundary and coarse "
                                      "floor plan (where there is navigable area), given before the start), which only "
                                      "the simulator's missions give"),
    ({"radio": {"backend": "sim"}}, "[robot] radio_profile: missing: the [radio] (sim) needs the team's radio profile"),
    ({"radio": {"backend": "rn2483", "port": "/dev/ttyUSB0", "baud": 9600}, "robot": {"radio_profile": "eu868-g3"}},
     "[radio] baud: unknown setting; backend 'rn2483' takes port, baudrate"),
    ({"radio": {"backend": "rn2483"}, "robot": {"radio_profile": "eu868-g3"}}, "[radio] port: missing"),
    ({"drive": {**DRIVE, "wheel_radius_m": "8 cm"}}, "[drive] wheel_radius_m: expected a number, 0 < X <= 5 m, "
                                                     "got '8 cm' (a string)"),
    ({"drive": {**DRIVE, "wheel_radius_m": -0.08}}, "[drive] wheel_radius_m: -0.08 is out of range; valid: a "
                                                    "number, 0 < X <= 5 m"),
    ({"drive": {**DRIVE, "max_v_mps": float("nan")}}, "[drive] max_v_mps: nan is not a finite number"),
    ({"drive": {**DRIVE, "channel": None}}, "[drive] channel: missing"),
    ({"drive": {**DRIVE, "interface": "socketcam"}}, "[drive] interface: 'socketcam' is no python-can interface"),
    ({"drive": {**DRIVE, "right_node": 0}}, "[drive] right_node: 0 is left_node's too"),
    ({"drive": {**DRIVE, "left_direction": 2}}, "[drive] left_direction: 2 is not one of 1, -1"),
    ({"lidar": {"backend": "rplidar"}}, "[lidar] port: missing: the scanner's serial device"),
    ({"lidar": {"backend": "rplidar", "port": "/dev/ttyUSB1", "range_max_m": 20.0}},
     "[lidar] range_max_m: 20.0 is out of range; valid: a number, 0 < X <= 16.3837 m"),
    ({"lidar": {"backend": "rplidar", "port": "/dev/ttyUSB1", "motor_pwm": 1024}},
     "[lidar] motor_pwm: 1024 is out of range; valid: an integer, 0 <= X <= 1023"),
    ({"uwb": {"backend": "dwm1001", "port": "/dev/ttyACM0", "peer_addresses": "1=0x1A2B"}},
     "[uwb] peer_addresses: '1=0x1A2B' is not ROBOT:ADDRESS"),
    ({"uwb": {"backend": "dwm1001", "port": "/dev/ttyACM0", "peer_addresses": "1:0x1A2B, 2:1a2b"}},
     "[uwb] peer_addresses: '2:1a2b': address 0x1A2B is robot 1's too"),
    ({"uwb": {"backend": "dwm1001", "port": "/dev/ttyACM0", "peer_addresses": "1:0x1A2B, 1:0x1A2C"}},
     "[uwb] peer_addresses: '1:0x1A2C': robot 1 is given twice"),
    ({"uwb": {"backend": "dwm1001", "port": "/dev/ttyACM0", "peer_addresses": "1:0x10000"}},
     "[uwb] peer_addresses: '1:0x10000': address 0x10000 is not a 16-bit short address"),
    ({"drive": DRIVE, "odometry": {**ODRIVE, "wheel_radius_m": 0.09}},
     "[odometry] wheel_radius_m: 0.09, but [drive] wheel_radius_m is 0.08: both tables describe one odrive-can"),
]


@pytest.mark.parametrize("changes, says", MISTAKES, ids=[says.split(":")[0] + f"-{i}" for i, (_, says)
                                                        in enumerate(MISTAKES)])
def test_every_mistake_names_the_file_the_table_and_the_key(changes, says, tmp_path, cli):
    path = write(tmp_path, changed(SIM, changes))
    r = cli("robot", "--config", path, "--check")
    assert r.code == 2, r
    assert f"lorascout robot: {path}: {says}" in r.err, r
    assert "Traceback" not in r.err


@pytest.mark.parametrize("text, says", [
    ("[robot]\nid = \n", "TOML syntax: Invalid value (at line 2, column 6)"),
    ("[robot]\nid = 0\n[robot]\n", "TOML syntax: Cannot declare ('robot',) twice (at line 3, column 7)"),
    ("id = 0\n[robot]\n", "id: a key outside every table; settings belong in a table ([robot], [params]"),
])
def test_syntax_errors_give_the_line_and_column(text, says, tmp_path, cli):
    path = write(tmp_path, text)
    r = cli("robot", "--config", path, "--check")
    assert r.code == 2 and f"{path}: {says}" in r.err, r


def test_a_file_that_is_not_utf8_is_refused(tmp_path, cli):
    path = tmp_path / "robot.toml"
    path.write_bytes(b"[robot]\nid = 0 # \xff\n")
    r = cli("robot", "--config", path, "--check")
    assert r.code == 2 and f"{path}: not UTF-8 text (line 2, byte 17)" in r.err, r


def test_a_params_table_of_the_scheme_sets_its_own_parameters(tmp_path):
    cfg = load_robot_config(write(tmp_path, changed(SIM, {"robot": {"scheme": "wiserx:blind"},
                                                          "params": {"wiserx.kappa1_m": 5, "d_cam_m": 3.0}})))
    assert cfg.describe()["params_overrides"] == {"d_cam_m": 3.0, "wiserx.kappa1_m": 5.0}


def test_optional_peripherals_left_out_are_null_and_the_clock_monotonic(tmp_path):
    cfg = load_robot_config(write(tmp_path, SIM))
    assert {p.kind: p.backend for p in cfg.peripherals} == {
        "clock": "monotonic", "lidar": "sim", "odometry": "sim", "drive": "sim", "radio": "null", "uwb": "null",
        "aoa": "null", "mesh": "null"}
    assert cfg.world == {"map": "cave:1:20x20", "seed": 0, "wheel_slip_frac": 0.0, "lidar_phase_ms": 0.0}
    odometry = next(p for p in cfg.peripherals if p.kind == "odometry")
    assert odometry.settings == {"frame": "shared"}            # the default, filled in


def test_the_real_example_is_checked_without_opening_a_device(cli, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("a device was opened during --check")

    monkeypatch.setattr(serial, "serial_for_url", refuse)
    monkeypatch.setattr(can, "Bus", refuse)
    r = cli("robot", "--config", REAL_EXAMPLE, "--check", "--json")
    assert r.code == 0, r
    checked = json.loads(r.out)
    assert checked["robot_id"] == 1 and checked["team_size"] == 3 and checked["radio_profile"] == "eu868-g3"
    peripherals = checked["peripherals"]
    assert peripherals["radio"] == {"backend": "rn2483", "port": "/dev/ttyUSB0", "baudrate": 57600,
                                    "reply_timeout_s": 2.0, "reset_timeout_s": 3.0, "configure": True}
    assert peripherals["drive"]["backend"] == "odrive-can" and peripherals["drive"]["channel"] == "can0"
    assert peripherals["odometry"]["start_x_m"] == 2.0 and peripherals["clock"] == {"backend": "monotonic"}
    assert peripherals["lidar"] == {"backend": "rplidar", "port": "/dev/ttyUSB1", "baudrate": 115200, "beams": 360,
                                    "range_max_m": 12.0, "reply_timeout_s": 1.0, "min_nodes_per_revolution": 36}
    assert peripherals["uwb"] == {"backend": "dwm1001", "port": "/dev/ttyACM0", "baudrate": 115200,
                                  "poll_hz": 10.0, "reply_timeout_s": 1.0, "peer_addresses": "0:0x1A2B, 2:0x1A2D"}
    r = cli("robot", "--config", REAL_EXAMPLE, "--check")
    assert r.code == 0 and "robot-real.toml: valid (nothing opened)" in r.out, r


def test_the_sim_example_is_valid_and_the_help_lists_every_backend_and_key(cli):
    r = cli("robot", "--config", SIM_EXAMPLE, "--check")
    assert r.code == 0 and "world          map='cave:1:30x30', seed=0" in r.out, r
    r = cli("robot", "--help")
    assert r.code == 0
    for kind, names in BACKENDS.items():
        assert f"[{kind}]  backend = {' | '.join(repr(n) for n in names)}" in r.out
    assert "wheel_radius_m (a number, 0 < X <= 5 m; required): wheel radius" in r.out
    assert "a run over it is an overrun" in r.out


def test_every_registered_backend_is_built_from_configuration_alike():
    """The registry's contract (hal.config): declared settings, resources the configuration
    can provide, and a from_config classmethod."""
    for kind, names in BACKENDS.items():
        for name in names:
            cls = backend_class(kind, name)
            assert isinstance(cls.SETTINGS, tuple) and all(isinstance(s, Setting) for s in cls.SETTINGS), cls
            assert all(r in RESOURCE_TABLES for r in cls.RESOURCES), cls
            assert callable(cls.from_config), cls
    assert config_help().count("backend = ") == len(BACKENDS)


# ---- backends from configuration ---------------------------------------------------------------

def test_the_monotonic_clock_counts_microseconds_from_its_start_and_is_one_per_robot():
    ctx = BuildContext(robot_id=0)
    clock = build_backend("clock", "monotonic", {}, ctx)
    assert build_backend("clock", "monotonic", {}, ctx) is clock and isinstance(clock, MonotonicClock)
    t0 = clock.now_us()
    assert 0 <= t0 < 1_000_000
    clock.sleep_until_us(t0 + 20_000)
    assert clock.now_us() >= t0 + 20_000


def test_the_odrive_backends_share_one_bus_arm_on_start_and_disarm_on_close():
    channel = f"odrive-config-{next(_channels)}"
    settings = {**ODRIVE, "channel": channel}
    del settings["backend"]
    axes = FakeAxes(channel, DiffDriveGeometry(left_node=0, right_node=1, wheel_radius_m=0.08, track_width_m=0.4))
    ctx = BuildContext(robot_id=0)
    ctx.clock = ManualWallClock()
    try:
        odometry = build_backend("odometry", "odrive-can", check_backend("odometry", "odrive-can", settings), ctx)
        drive_settings = check_backend("drive", "odrive-can", {**settings, "max_v_mps": 0.8, "max_omega_radps": 1.5,
                                                               "robot_radius_m": 0.25})
        drive = build_backend("drive", "odrive-can", drive_settings, ctx)
        assert drive._bus is odometry._bus
        axes.take_commands()
        assert set(axes.state.values()) == {AXIS_STATE_CLOSED_LOOP_CONTROL}
        drive.command(0.5, 0.0)
        axes.take_commands()
        assert axes.velocity[0] != 0.0
        assert ctx.close() == []
        axes.take_commands()
        assert set(axes.state.values()) == {AXIS_STATE_IDLE} and set(axes.velocity.values()) == {0.0}
        with pytest.raises(can.CanOperationError):
            drive.command(0.1, 0.0)               # the bus was shut down
    finally:
        axes.bus.shutdown()


def test_a_device_that_fails_to_open_closes_what_was_opened_before_it(tmp_path, cli):
    channel = f"odrive-config-{next(_channels)}"
    axes = FakeAxes(channel, DiffDriveGeometry(left_node=0, right_node=1, wheel_radius_m=0.08, track_width_m=0.4))
    tables = changed(SIM, {"drive": {**DRIVE, "channel": channel}, "odometry": {**ODRIVE, "channel": channel},
                           "radio": {"backend": "rn2483", "port": str(tmp_path / "no-such-tty")},
                           "robot": {"radio_profile": "eu868-g3"}})
    try:
        says = r"\[radio\] backend = 'rn2483': cannot start: Rn2483Error: .*no-such-tty"
        with pytest.raises(DeviceError, match=says):
            open_robot(load_robot_config(write(tmp_path, tables)))
        axes.take_commands()                      # the drive was armed, then disarmed when the radio failed
        assert set(axes.state.values()) == {AXIS_STATE_IDLE}
        r = cli("robot", "--config", tmp_path / "robot.toml")
        assert r.code == 1 and "[radio] backend = 'rn2483': cannot start" in r.err, r
    finally:
        axes.bus.shutdown()


# ---- the tick loop: overruns against each task's budget --------------------------------------

def test_overruns_are_counted_against_each_tasks_budget_and_late_ticks_skipped(caplog):
    """A scripted task (10 Hz, budget 20 ms) whose runs take 5, 30, 120 and 10 ms in turn, on
    a clock that moves only by that work: at 0 (5 ms), 100 (30: over), 200 (120: over, and
    the tick over its 50 ms, so the slot at 250 is skipped), 320 (10), 400 (5), 500 (30:
    over), 600 (120: over, the slot at 650 skipped); then 0.6 s have passed."""
    clock = ManualWallClock()
    agent = ExplorerAgent(dataclasses.replace(ScriptedHal(np.full(360, 8.0)).hal(), clock=clock), scheme="independent")
    agent.setup()
    slow = ScriptedSlowTask(clock, [5_000, 30_000, 120_000, 10_000])
    agent.scheduler.tasks.append(Task("slow", 10.0, slow, budget_us=20_000))
    with caplog.at_level(logging.INFO, logger="lorascout.robot"):
        result = RobotLoop(agent, clock, log_interval_s=0.25).run(lambda: None, max_s=0.6)
    assert result.termination == "time_limit" and result.wall_s == 0.72
    assert (result.ticks, result.ticks_skipped, result.tick.overruns) == (12, 2, 2)
    s = result.tasks["slow"]
    assert (s.runs, s.overruns, s.max_us, s.budget_us) == (7, 4, 120_000, 20_000)
    assert all(result.tasks[t].overruns == 0 for t in ("radio", "lidar", "control", "planning"))
    assert result.tasks["radio"].budget_us == 50_000 and result.tasks["planning"].budget_us == 1_000_000
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warnings and "slow 2/3" in warnings[0] and "(1 over 50 ms, 1 skipped)" in warnings[0]


def test_a_late_loop_keeps_the_tick_grid():
    assert next_tick(0, 10_000, 50_000) == (50_000, 0)          # on time
    assert next_tick(0, 70_000, 50_000) == (50_000, 0)          # late: the next tick at once
    assert next_tick(0, 120_000, 50_000) == (100_000, 1)        # a whole slot passed: skipped


def radio_robot(clock: ManualWallClock, radio: FakeRadio, robot_id: int = 0) -> ExplorerAgent:
    """Robot `robot_id` of two on eu868-g3 (MinPos), standing still on the scripted HAL with
    `radio`, whose time follows `clock`."""
    hal = dataclasses.replace(ScriptedHal(np.full(360, 8.0)).hal(), clock=clock, radio=radio, robot_id=robot_id)
    agent = ExplorerAgent(hal, scheme="bayer-faigl:minpos", radio_profile=PROFILES["eu868-g3"], team_size=2)
    agent.setup()
    return agent


def test_a_done_robot_signs_off_and_stops_once_its_heartbeat_has_left_the_air(caplog):
    """Done, with no teammate exploring: the loop has the firmware queue its heartbeat (done)
    and ends "complete" only after that frame has gone out in the robot's TDMA slot and ended
    on the air, so a teammate that missed the earlier one hears it now."""
    clock, radio = ManualWallClock(), FakeRadio(PROFILES["eu868-g3"])
    clock.t_us = 1_000_000                       # robot 1's slot is [450, 900) ms of each 900 ms frame
    agent = radio_robot(clock, radio, robot_id=1)
    agent.done = True
    with caplog.at_level(logging.INFO, logger="lorascout.robot"):
        result = RobotLoop(agent, clock, followers=[lambda t: setattr(radio, "now_us", t)]).run(lambda: None)
    assert result.termination == "complete" and result.sign_off == "sent", result
    assert len(radio.sent) == 1
    sent_us, payload = radio.sent[0]
    frame = decode_frame(payload).frame
    assert frame.sender_id == 1 and [(name, v["done"]) for name, v in frame.records] == [("pose", 1)]
    assert sent_us == 1_350_000                  # the first tick in its slot (1.35 s = 0.9 + 0.45)
    ended_on_air_us, loop_ended_us = sent_us + PROFILES["eu868-g3"].airtime_us(len(payload)), clock.t_us
    assert ended_on_air_us <= loop_ended_us < ended_on_air_us + 100_000
    assert result.sign_off_s == result.wall_s == (loop_ended_us - 1_000_000) / 1e6
    assert result.to_json()["sign_off"] == "sent"
    assert any("signing off" in r.getMessage() for r in caplog.records)


def test_a_robot_whose_radio_cannot_send_stops_after_the_sign_off_timeout(caplog):
    """A modem that refuses every frame must not keep a finished robot: it stops complete after
    SIGN_OFF_FRAMES TDMA frames (3 x 900 ms on eu868-g3 for two), with a warning."""
    clock, radio = ManualWallClock(), FakeRadio(PROFILES["eu868-g3"], refuse=True)
    agent = radio_robot(clock, radio)
    agent.done = True
    with caplog.at_level(logging.INFO, logger="lorascout.robot"):
        result = RobotLoop(agent, clock, followers=[lambda t: setattr(radio, "now_us", t)]).run(lambda: None)
    assert result.termination == "complete" and result.sign_off == "timed_out" and radio.sent == []
    assert SIGN_OFF_FRAMES == 3 and result.sign_off_s == 2.7 and result.wall_s == 2.7
    assert any(r.levelno == logging.WARNING and "has not left the air" in r.getMessage() for r in caplog.records)


def test_a_teammate_heard_exploring_again_calls_the_sign_off_off():
    """Signing off (its heartbeat waits for its slot), the robot hears robot 1 exploring: it
    stays, and runs until something else ends it."""
    clock, radio = ManualWallClock(), FakeRadio(PROFILES["eu868-g3"])
    clock.t_us = 500_000                         # robot 0's slot opens at 900 ms
    agent = radio_robot(clock, radio)
    agent.done = True

    def teammate_explores(t_us: int) -> None:
        radio.now_us = t_us
        if t_us == 600_000:
            agent.roster.heard_status(1, 3.0, 4.0, False, t_us)

    result = RobotLoop(agent, clock, followers=[teammate_explores]).run(lambda: None, max_s=3.0)
    assert result.termination == "time_limit" and result.sign_off is None


def test_a_signal_ends_the_loop_after_the_tick_and_a_done_robot_stops_by_itself():
    clock = ManualWallClock()
    agent = ExplorerAgent(dataclasses.replace(ScriptedHal(np.full(360, 8.0)).hal(), clock=clock), scheme="independent")
    agent.setup()
    asked = iter([None, None, None, "SIGTERM"])
    result = RobotLoop(agent, clock).run(lambda: next(asked, "SIGTERM"))
    assert result.termination == "SIGTERM" and result.ticks == 1
    agent.done = True
    done = RobotLoop(agent, clock).run(lambda: None)
    assert done.termination == "complete" and done.sign_off == "no_radio"     # nothing to sign off with


# ---- the simulated robot, as a user runs it ----------------------------------------------------

@pytest.mark.realtime
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_the_sim_example_runs_in_real_time_until_a_signal_stops_it_with_the_drive_at_zero(sig):
    with RobotProcess("--config", str(SIM_EXAMPLE), "--json", "--log-interval-s", "0.5") as robot:
        robot.wait_for_log("robot 0 of 1 started", timeout_s=120)   # after the kernels compiled
        started = time.monotonic()
        robot.wait_for_log("task overruns radio", timeout_s=10)
        time.sleep(max(0.0, 1.2 - (time.monotonic() - started)))
        code, out = robot.stop(sig)
    assert code == 0, robot.log_lines[-20:]
    report = json.loads(out)
    assert report["termination"] == sig.name and report["status"] == "exploring"
    assert report["ticks"] >= 15 and report["world"]["sim_s"] >= 1.0    # the world kept up with the wall clock
    assert report["world"]["path_length_m"] > 0.0                      # it drove
    assert report["drive_stopped"] and report["world"]["drive_command"] == {"v_mps": 0.0, "omega_radps": 0.0}
    assert report["close_failures"] == [] and report["error"] is None
    assert set(report["tasks"]) == {"radio", "heartbeat", "lidar", "control", "planning"}


def test_a_failure_while_running_still_stops_the_drive_and_closes_everything(tmp_path, cli, monkeypatch, caplog):
    def lost(self, now_us):
        raise OSError("serial line lost")

    monkeypatch.setattr(ExplorerAgent, "_task_lidar", lost)   # a device error surfacing in a task
    r = cli("robot", "--config", write(tmp_path, SIM), "--json", "--max-s", "5")
    assert r.code == 1, r
    report = json.loads(r.out)
    assert report["termination"] == "error" and report["error"] == "OSError: serial line lost"
    assert report["ticks"] == 0 and report["drive_stopped"] and report["close_failures"] == []
    assert report["world"]["drive_command"] == {"v_mps": 0.0, "omega_radps": 0.0}
    assert any(rec.getMessage() == "the tick loop failed" and rec.exc_info for rec in caplog.records)

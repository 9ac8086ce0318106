"""A team on one clock: `[clock] epoch_ns` gives a robot's monotonic clock the zero another
process took (`lorascout hil` gives every robot the world's), a configuration whose epoch lies
in the future is refused before anything starts, and the tick loop ticks on multiples of the
tick period of that clock, so robots sharing an epoch tick, and key their TDMA slots, together."""
import dataclasses
import re
import time

import numpy as np

from firmware.agent import ExplorerAgent
from firmware.scheduler import Task
from hal.config import BuildContext
from hal.monotonic_clock import EPOCH_AHEAD_TOLERANCE_NS, MonotonicClock
from hal.registry import build_backend, check_backend
from host_tools.robot_config import load_robot_config
from host_tools.robot_loop import RobotLoop
from tests.doubles import ManualWallClock, ScriptedHal, ScriptedSlowTask

ROBOT = ('[robot]\nid = 0\nscheme = "independent"\n[world]\nmap = "cave:1:20x20"\n'
         '[lidar]\nbackend = "sim"\n[odometry]\nbackend = "sim"\n[drive]\nbackend = "sim"\n')


def test_a_clock_given_an_epoch_reads_the_time_since_it():
    epoch_ns = time.monotonic_ns() - 7_000_000_000          # 7 s ago, as another process took it
    ctx = BuildContext(robot_id=0)
    clock = build_backend("clock", "monotonic", check_backend("clock", "monotonic", {"epoch_ns": epoch_ns}), ctx)
    before_ns = time.monotonic_ns()
    read_us = clock.now_us()
    after_ns = time.monotonic_ns()
    assert (before_ns - epoch_ns) // 1000 <= read_us <= (after_ns - epoch_ns) // 1000
    assert clock.epoch_ns == epoch_ns
    # Two clocks with one epoch read the same time; without one, a clock starts near zero.
    other = MonotonicClock(epoch_ns)
    assert abs(other.now_us() - clock.now_us()) < 50_000
    assert 0 <= MonotonicClock().now_us() < 1_000_000


def test_a_configuration_whose_epoch_lies_in_the_future_is_refused_naming_the_key(tmp_path, cli):
    path = tmp_path / "robot.toml"
    ahead_ns = time.monotonic_ns() + 60_000_000_000
    path.write_text(ROBOT + f'[clock]\nbackend = "monotonic"\nepoch_ns = {ahead_ns}\n')
    r = cli("robot", "--config", path, "--check")
    assert r.code == 2, r
    assert re.search(rf"^lorascout robot: {re.escape(str(path))}: \[clock\] epoch_ns: {ahead_ns} lies 5\d\.\d+ s "
                     "in the future of this machine's monotonic clock", r.err), r
    assert "Traceback" not in r.err, r
    # Within the tolerance, or in the past, it is accepted; so is the key left out.
    for epoch_ns in (time.monotonic_ns() + EPOCH_AHEAD_TOLERANCE_NS // 2, time.monotonic_ns() - 10**9):
        path.write_text(ROBOT + f'[clock]\nbackend = "monotonic"\nepoch_ns = {epoch_ns}\n')
        clock = next(p for p in load_robot_config(path).peripherals if p.kind == "clock")
        assert clock.settings == {"epoch_ns": epoch_ns}
    path.write_text(ROBOT + '[clock]\nbackend = "monotonic"\n')
    assert next(p for p in load_robot_config(path).peripherals if p.kind == "clock").settings == {}
    path.write_text(ROBOT + '[clock]\nbackend = "monotonic"\nepoch_ns = -1\n')
    r = cli("robot", "--config", path, "--check")
    assert r.code == 2 and f"{path}: [clock] epoch_ns: -1 is out of range" in r.err, r


def test_the_loop_ticks_on_multiples_of_the_tick_period_of_its_clock():
    """A loop started off the grid (at 1.234567 s) ticks first at 1.25 s and then every 50 ms
    on the grid, also after a task that ran late (35 and 80 ms: the tick after the second
    starts at once, the one after that back on the grid)."""
    clock = ManualWallClock()
    clock.t_us = 1_234_567
    agent = ExplorerAgent(dataclasses.replace(ScriptedHal(np.full(360, 8.0)).hal(), clock=clock), scheme="independent")
    agent.setup()
    agent.scheduler.tasks.append(Task("slow", 10.0, ScriptedSlowTask(clock, [1_000, 35_000, 80_000, 2_000]),
                                      budget_us=100_000))
    ticks = []
    result = RobotLoop(agent, clock, followers=[ticks.append]).run(lambda: None, max_s=1.0)
    tick_us = agent.rates.tick_period_us
    assert tick_us == 50_000 and result.ticks == len(ticks) > 15
    assert ticks[0] == 1_250_000
    late = [t for t in ticks if t % tick_us]
    assert late == [1_480_000, 1_880_000]                    # after the 80 ms runs, at 1.4 and 1.8 s
    assert all(t % tick_us == 0 for t in ticks if t not in late)
    # The only ticks off the grid are those that began at once after a late one, and the next
    # is back on it.
    for t in late:
        i = ticks.index(t)
        assert ticks[i - 1] % tick_us == 0 and t - ticks[i - 1] > tick_us and ticks[i + 1] % tick_us == 0
    assert result.started_s == 1.234567 and result.ended_s == clock.t_us / 1e6
    assert result.to_json()["started_s"] == 1.235

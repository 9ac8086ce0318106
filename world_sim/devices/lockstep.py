"""A mission's serial sensors: every robot's LiDAR (and UWB module) emulated on its own pty,
read by the real drivers, advanced in lockstep with the world.

The runner owns time. After each world step it calls `advance_to(now_us)`, which
1. lets every emulator take what the world measured up to now (a scan is written whole,
   UWB ranges wait for the driver's next question), then
2. makes every driver catch up: a LiDAR driver waits until it has received every byte its
   emulator has written (the emulator counts them), and assembles the revolutions they
   carry; a UWB driver asks its module for new location data and waits for the answer.
So when the firmware ticks next, its drivers hold exactly what the world had measured up to
that tick, whatever the kernel's scheduling of pty bytes, as the RN2483 bank does for the
radios (radio_sim.virtual_modem).
"""
from __future__ import annotations

from world_sim.devices.dwm1001_emulator import Dwm1001Emulator
from world_sim.devices.rplidar_emulator import RplidarEmulator
from world_sim.world import World


class LockstepSerialSensors:
    def __init__(self) -> None:
        self.lidars: list[tuple[RplidarEmulator, object]] = []     # (emulator, hal.rplidar.RplidarLidar)
        self.rangers: list[tuple[Dwm1001Emulator, object]] = []    # (emulator, hal.dwm1001.Dwm1001Ranger)

    def advance_to(self, now_us: int) -> None:
        for emulator, _ in self.lidars:
            emulator.advance_to(now_us)
        for emulator, _ in self.rangers:
            emulator.advance_to(now_us)
        for emulator, driver in self.lidars:
            driver.sync(emulator.bytes_queued)
        for _, driver in self.rangers:
            driver.sync()

    def close(self) -> None:
        for emulator, driver in self.lidars + self.rangers:
            driver.close()
            emulator.close()


def open_serial_sensors(world: World, clock, *, lidar: bool, uwb: bool) -> tuple[LockstepSerialSensors, list, list]:
    """For every robot of `world`: an emulated RPLIDAR read by hal.rplidar.RplidarLidar (if
    `lidar`) and an emulated DWM1001 read by hal.dwm1001.Dwm1001Ranger (if `uwb`), all in
    lockstep mode. Returns (link, lidars, rangers), the drivers in robot order (empty lists
    for what was not asked for); the link has already handed over what the world measured
    at the start. Call link.advance_to(clock.now_us()) after each world step and
    link.close() at the end (it closes the drivers too)."""
    from hal.dwm1001 import Dwm1001Ranger
    from hal.rplidar import RplidarLidar

    link = LockstepSerialSensors()
    try:
        p = world.params
        for i in range(world.n_robots if lidar else 0):
            emulator = RplidarEmulator(world, i)
            link.lidars.append((emulator, None))
            driver = RplidarLidar(emulator.path, clock, beams=p.lidar_beams, range_max_m=p.lidar_range_m,
                                  lockstep=True)
            link.lidars[-1] = (emulator, driver)
        for i in range(world.n_robots if uwb else 0):
            emulator = Dwm1001Emulator(world, i)
            link.rangers.append((emulator, None))
            driver = Dwm1001Ranger(emulator.path, clock, lockstep=True)
            link.rangers[-1] = (emulator, driver)
        link.advance_to(clock.now_us())
    except BaseException:
        for emulator, driver in link.lidars + link.rangers:
            if driver is not None:
                driver.close()
            emulator.close()
        raise
    return link, [d for _, d in link.lidars], [d for _, d in link.rangers]

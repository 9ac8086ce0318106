"""Emulated serial devices driven by the simulated world: an RPLIDAR scanner and a DWM1001
UWB module per robot, each on a pseudo-terminal, so the real drivers (hal.rplidar,
hal.dwm1001) run unchanged against the simulation (ArduPilot SITL's pattern)."""

"""Emulated devices driven by the simulated world, so the real drivers run unchanged against
the simulation (ArduPilot SITL's pattern): an RPLIDAR scanner and a DWM1001 UWB module per
robot, each on a pseudo-terminal (hal.rplidar, hal.dwm1001), and the ODrive axes of a robot's
differential drive on a python-can bus (hal.odrive_can)."""

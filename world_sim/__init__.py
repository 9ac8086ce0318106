"""The simulated physical world: ground-truth maps, robot bodies, ray casting.

Only the simulator and the simulated HAL backends see this package; the firmware never does.
"""

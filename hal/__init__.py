"""Hardware abstraction layer: what the firmware may know about the robot.

`hal.samples` and `hal.interfaces` are all the firmware sees. Backends (simulated under
`hal.sim`, real ones beside it) are chosen by name through `hal.registry`.
"""

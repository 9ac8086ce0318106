"""WiSER-X (Jadhav et al., arXiv 2412.19876; ../shared/schemes/wiserx.md; issue 24): exploration
coordinated by UWB ranges and WiFi angle-of-arrival bearings alone.

Not a scheme yet: nothing here is registered in firmware.schemes.SCHEMES, and no robot runs it.

What exists:
- ekf.py: the relative-position EKF of issue 24 item 1 (spec sections 1.2, 1.3, 2, A1-A5):
  per teammate, position and velocity in this robot's own odometry frame; white-noise
  acceleration motion; UWB range and AoA bearing updates, sequential (each sample at its own
  time) or in windows (AverageDist and StableBearingAngle); chi-square gating, wrapped
  bearing residuals, Joseph-form covariance, polar start. Tested by tests/test_wiserx_ekf.py
  (unit tests of section 6.1, NEES/NIS setups A1 and A2 of section 6.2).
- params.py: its constants (EkfParams), with units and valid ranges.

What does not exist yet: the per-peer track layer `relpos` (sample pairing with own poses
from services.pose, the K = 5 circular-median bearing check and the 3 m range-jump rule of
A3/A4, boundary rejection, silence-detected failure tau), the PDAF over top-N AoA peaks,
NLOS inflation of R (A30), the hgrid coverage record, frontiers and the utility of eqs. 2-7,
commitment, soft and hard termination, the relsense task, the scheme class and its variants
(wiserx, wiserx-lora, wiserx-blind, divide), and the optional LoRa digest record.
The simulated sensing profiles it is meant to run on are in world_sim/sensing.py.
"""

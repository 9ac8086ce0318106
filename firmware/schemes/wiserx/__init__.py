"""WiSER-X (Jadhav et al., arXiv 2412.19876; ../shared/schemes/wiserx.md; issue 24): exploration
coordinated by UWB ranges and WiFi angle-of-arrival bearings alone; nothing on the LoRa air.

    ekf.py      the relative-position EKF per teammate (sections 1.2, 1.3, A1-A5), tested by
                tests/test_wiserx_ekf.py (unit tests of 6.1, NEES/NIS setups A1 and A2 of 6.2)
    relpos.py   the track layer in front of it: samples paired with the own pose of their
                time, the bearing-median and range-jump rules (A3, A4), paired samples as a
                converted position measurement, silence-detected failure with revival (A18)
    hgrid.py    the coverage record: own positions and teammate estimates, tau per robot,
                disc / pts2 fill over the footprint (1.4, A6-A9, 5.8)
    utility.py  eqs. (2)-(7): S, E, I, I_0, the loss ratio, beta, U
    scheme.py   the Scheme: relsense task, soft and hard termination, commitment; variants
                complete (default), paper, blind (alias wiserx-blind)
    params.py   EkfParams and WiserxParams, with units and valid ranges

Not built: the PDAF over top-N AoA peaks, NLOS inflation of R (A30), window-mode updates in
the scheme (ekf.py has them), frontier clusters with PCA split as viewpoints (the shared
planner's waypoints are the viewpoints), the `wiserx-lora` variant. The `divide` baseline is
a scheme of its own (firmware/schemes/divide); failed and slow robots are the simulator's
(host_tools.mission: --fail, --slow).
The simulated sensing profiles it runs on are in world_sim/sensing.py.
"""

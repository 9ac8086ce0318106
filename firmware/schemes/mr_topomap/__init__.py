"""MR-TopoMap (Zhang et al., RA-L 2022; issue 25; `../shared/schemes/mrtopomap.md`): a
topological map whose vertices carry a place descriptor and unexplored directions, merged
between robots WITHOUT a common frame by recognising shared places.

What exists (issue 25 items 2, 3 and 6, the first landable pieces):

    params.py       the parameters (spec section 2), until they move to firmware/params.py
    descriptor.py   the place descriptor from a 2-D LiDAR scan: 32 bins of log range in the
                    robot's own frame, 4-bit z-scored; rotation-invariant score, the relative
                    yaw from its best circular shift; virtual profiles of an own map
    records.py      the dialect (id 5, NOT registered): mrvtx 30 B (vertex, descriptor,
                    unexplored directions, its line-17 edge), mredge 6 B, mrud 6 B, mrlink 9 B
    directions.py   unexplored directions from the own map (16 sectors x distance class),
                    explored-direction updates, the per-vertex book of open sectors
    vertices.py     Algorithm 1 fed with poses and scans: new vertices and re-entry edges
    merge.py        Algorithm 2 made frame-free: SE(2) hypotheses from descriptor matches
                    (own vertices, optionally a profile grid of the own map), deterministic
                    consensus, ratio test, occupancy and view checks against the own map; a
                    pure function of the records held (so merges revise themselves)

Where this departs from the spec (each says why where it is done): the view check and
k_min = 4 in merge.py, the profile grid's distinct places instead of its 3 best cells, the
re-entry nearness rule in vertices.py, the fit's blend of descriptor and Procrustes yaw.

What does not exist yet: the Scheme subclass and its registration (firmware/schemes/__init__.py),
the dialect in firmware.schemes.all_dialects() (and so the README table, fingerprint and
dissector), the merged graph for planning (vertices and edges of merged teammates in the own
frame, Dijkstra), exploration (eq. 1, direction choice, anti-trap, termination), the literal
ablation (translation-only first-match merge with SMMR's 0.9-sigma rule), mrlink use
(transitive merges), and the simulator's own-frame odometry and spread starts (issue 25 item 1).
Nothing here is wired into the agent.
"""

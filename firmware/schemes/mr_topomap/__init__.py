"""MR-TopoMap (Zhang et al., RA-L 2022; issue 25; `../shared/schemes/mrtopomap.md`): a
topological map whose vertices carry a place descriptor and unexplored directions, merged
between robots WITHOUT a common frame by recognising shared places.

What exists:

    params.py       the geometry and the tuning knobs (spec sections 2, 4, 5), declared
                    with units and ranges (--set mrtopomap.NAME=VALUE)
    descriptor.py   the place descriptor from a 2-D LiDAR scan: 32 bins of log range in the
                    robot's own frame, 4-bit z-scored; rotation-invariant score, the relative
                    yaw from its best circular shift; virtual profiles of an own map
    records.py      the dialect (id 5, registered through the scheme): mrvtx 30 B (vertex,
                    descriptor, unexplored directions, its line-17 edge), mredge 6 B, mrud
                    6 B, mrlink 9 B
    directions.py   unexplored directions from the own map (16 sectors x distance class),
                    explored-direction updates, the per-vertex book of open sectors
    vertices.py     Algorithm 1 fed with poses and scans: new vertices and re-entry edges
    merge.py        Algorithm 2 made frame-free: SE(2) hypotheses from descriptor matches
                    (own vertices, optionally a profile grid of the own map), deterministic
                    consensus, ratio test, occupancy and view checks against the own map; a
                    pure function of the records held (so merges revise themselves)
    links.py        merges told on the air (mrlink): each robot's direct merges weighed
                    against what teammates' links say (the inverse, compositions through a
                    third robot), outvoted when the others agree elsewhere, and merges by
                    composition where the robot could not merge itself
    literal.py      the paper's own merge for the ablation: translation only, first match,
                    SMMR's 0.9-sigma rule
    scheme.py       the Scheme (`mrtopomap`, `mrtopomap:literal` = `mrtopomap-literal`):
                    Algorithm 1 on the robot's own odometry, records on the air, merges
                    every merge_period_s (params.py), merged teammates' vertices and directions in
                    planning (III-E updates, eq. (1), the goal and its fallback), termination
                    and waking up on teammates' open directions; needs no shared frame

Where this departs from the spec (each says why where it is done): the view check and
k_min = 4 in merge.py, the profile grid's distinct places instead of its 3 best cells, the
re-entry nearness rule in vertices.py, the fit's blend of descriptor and Procrustes yaw;
in scheme.py the own frontier waypoints as a completion after the directions, own waypoints
a merged teammate evidently saw left to it, and routes beyond the local window along the
robot's own places only.

What does not exist yet: routing along the merged graph (teammates' edges), the anti-trap
rule (III-D3), re-sending vertex records a teammate missed (one lost on the air is lost;
mrlink records repeat every link_period_s), stretching d_vertex to a slower band's budget
(5.1).
"""

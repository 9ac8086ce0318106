"""Pereira, Moreira & Veloso (CONTROLO 2014): exploration by regions whose statuses robots
merge without clocks (issue 23; `../shared/schemes/pereira.md`).

A registered scheme (`--scheme pereira`, firmware.schemes.SCHEMES); its dialect (id 3) is in
every node's dialect set, so `lorascout inspect`, the pcap export and the Wireshark
dissector decode it. Variants:

    pereira          regions cut at the gates the robots find in their own maps
    pereira:oracle   (alias pereira-oracle) regions cut at the doorways of a region map the
                     host loads before the mission (Pereira.load_region_map; the need
                     "region_map"): host_tools/region_oracle.py finds them with gates.py's
                     detector on the whole ground-truth map, the paper's hand-made regions'
                     stand-in. They are gate records of origin 254, held by every robot from
                     the start, never sent; an oracle robot finds no gates of its own. So
                     pereira / pereira:oracle measures what finding gates from partial,
                     drifting views and sharing them costs, not the detector's rule itself.
    pereira:nogossip (alias pereira-nogossip) no summaries and no pushes: a robot holds
                     only what it heard from the records' origins (the multi-hop ablation)

    scheme.py    the Scheme: places every d_build_m, gates confirmed in the robot's own
                 map every pereira_gate_period_s, the explored judgement (A2) and claims,
                 waypoints in regions teammates claimed left to them (A5, A6), categories
                 and eq. (3) as ranks, intents, summaries and pushes; stats and drawables
    labels.py    the private label grid (5.2 d): the window's FREE cells walked from the
                 places with the gates drawn as walls, so a waypoint is placed in the
                 region the robot could walk to it in, not through a wall no gate marks
    choice.py    the current and previous region with the margin (A7, A8), the four
                 frontier categories (1.5), Algorithm 1's conflict rule with eq. (3) (1.6)
    gossip.py    anti-entropy: who holds which records of which origin, what to push
                 to a robot whose summary lags (5.5)
    records.py   the dialect: place, gate, claim, intent, summary as fixed-size records
                 (9, 9, 10, 12, 16 B) with typed encode/decode
    gates.py     gates (doorways, corridor mouths) found in a robot's own occupancy grid,
                 their confirmation over cycles, and a place's certified free radius
    regions.py   the region graph (regions, anchors, signatures, adjacency through gates,
                 virtual regions behind gates) as a pure function of the place and gate
                 record set; claim anchors resolved to regions; points labelled with regions
    status.py    statuses as per-origin claims in a grow-only set: eq. 1 and 2, the
                 same-robot override and the loop rule, with no clock (a join)
    store.py     the records a robot holds, with the graph and the status view derived
    params.py    the detector's and the fold's geometry (the behaviour's parameters, with
                 units, are firmware/params.py's pereira_*, overridable with --set)

Limited range: `--range-m M` on `lorascout run` and `sweep` (radio_sim.channel.Channel's
max_range_m) cuts every link longer than M metres, the ideal link's included; records reach
robots out of range through the others' summaries and pushes (tests/test_pereira_range.py).

Not yet, or not as the spec says:
- the label grid covers the robot's window; points outside it (remembered waypoints,
  teammates' far goals) are still labelled by the nearest place with no gate between
  (RegionGraph.label), which can reach through a wall no gate marks;
- goal persistence (A18) is the shared choice's (keep the target unless another of no worse
  rank costs under 0.8 of it), not 1.25 x U;
- waypoints in regions no claim covers are dropped where what they promise was in view of
  the teammates' places (pereira_team_view: fewer than pereira_revive_left_bit unseen once
  a LiDAR at every teammate's place counts as having seen): A2's claims come late, and a
  region several robots explored in parts may never be claimed by any. That view is a
  model: its rays pass through what the robot's map shows unknown, so they stop at gates
  (pereira_gates_block_view: a teammate in a corridor does not see the rooms off it), and a
  robot claims no region where it dropped waypoints on it (a claim is a report teammates
  trust). It still leaves pockets on the Intel lab; without it (team_view off) the paper's
  eight-region map can end with both robots stopped at 0.70 (README, "Pereira et al.:
  the Intel lab");
- a robot with nothing else worth heading for while teammates explore keeps the waypoint
  on its shortest way (along the places' edges) to a region a teammate's intent heads for
  (pereira_transit), mapping its way through claimed regions, instead of stopping;
- a claim leaves to the team only the waypoints a teammate's place lies within d_cam_m of
  (pereira_claims_near_only): the label grid carries a claimed region's label through a
  doorway no gate marks into rooms no teammate came near, and without this test their
  waypoints were left to the claim and the room unseen (maze_b seed 5: a fifth of the
  maze, every robot stopped by itself). Those kept are ranked after every other waypoint
  (pereira_unseen_claimed_last);
- with pereira_place_skip_m > 0 (off by default) no place is sent where the region graph
  holds one that close; the spec sends one every d_place;
- the end-game safety net (the spec's) is off by default. Before the test above, a room no
  one entered was left unseen without it; with it for the last robot exploring
  (pereira_take_back_alone) that room is covered, but the last robot also retraces its
  teammates' regions, whose far rim its own map shows unknown (maze_a: p_max 1.7 times).
  While teammates explore (pereira_take_back) no run of the grids needed it once transit
  and the teammates' view were in. Either takes back rich waypoints
  (pereira_revive_min_bit) in claimed regions that no teammate left a place within
  revive_clear_m of and that keep pereira_revive_left_bit once the view from every
  teammate's place (not only the claimants') counts as seen; beyond the window only once
  every teammate is done, and only where no teammate's place lies within d_cam_m / 2. A
  robot that has already stopped is woken only by a retraction;
- a robot that stops claims every region it has mapped whole (its places all known, none of
  the frontiers it leaves in it, no teammate's claim on it), beyond A2's window;
- robots share no maps (as in the paper): what a waypoint promises is counted through the
  unknown beyond the robot's own map, so with pereira_take_back the last robot exploring
  takes back waypoints whose promise is the far rim of their reach, out of every teammate
  place's range (maze_a: see the README's "Pereira et al." sections);
- a robot sends no claim while a teammate's claim on the region holds (it would tell no
  one anything);
- a record is pushed to a teammate whose summary lacks it only if it was held already when
  that teammate's previous summary came: summaries are seconds old when heard, and in range
  with nothing lost the team pushed records everyone had just heard;
- a done robot sends one done intent, not one every 30 s (the heartbeat says done);
- a push is cancelled when another robot sends the record first, from the scheme's outbox
  or from the link, where it waits for the robot's TDMA slot (LinkLayer.withdraw);
- the oracle's region map is not loaded on a real robot (host_tools/robot_config has no
  file for it yet): only missions (`lorascout run`, `sweep`) hand it over;
- paths over the region graph (a transit is chosen along the places' edges, but driven on
  the robot's own map and places, like the no-sharing baseline's), the pereira-grid variant, the region overlay as filled areas, a numba fold,
  and the rest of the acceptance grid (the ideal link on maze_b and the Intel lab,
  pereira-oracle, ranges, loss; the four maps over eu868-g3 and maze_a and the cave over
  the ideal link ran);
- a finished robot no longer judges regions, so a region it claimed that grows a
  teammate's place (its signature changes) is never claimed again, and the teammate
  explores it anew (the paper's scaling experiment on tests/data/pereira8: see the
  README's "Pereira et al.").

The mission report holds each robot's digests of its record set and region graph
(Scheme.digests; `scheme_digests` in the JSON, with whether every robot holds the same),
and `--flush-s S` keeps the radios going after every robot has stopped, so records still
on their way arrive before they are compared (pereira.md 6.3 bar 8).
"""

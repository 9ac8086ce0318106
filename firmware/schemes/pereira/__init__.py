"""Pereira, Moreira & Veloso (CONTROLO 2014): exploration by regions whose statuses robots
merge without clocks (issue 23; `../shared/schemes/pereira.md`).

A registered scheme (`--scheme pereira`, firmware.schemes.SCHEMES); its dialect (id 3) is in
every node's dialect set, so `lorascout inspect`, the pcap export and the Wireshark
dissector decode it.

    scheme.py    the Scheme: places every d_build_m, gates confirmed in the robot's own
                 map every pereira_gate_period_s, the explored judgement (A2) and claims,
                 waypoints in regions teammates claimed left to them (A5, A6), categories
                 and eq. (3) as ranks, intents, summaries and pushes; stats and drawables
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

Not yet, or not as the spec says:
- the private label grid (5.2 d): waypoints are labelled by the nearest place with no gate
  between (RegionGraph.label), which can reach through a wall no gate marks;
- within a category the shared choice takes the cheapest path, not the spec's
  U = e_bit / (cost + 1) (the spec's `pereira_order=cost` ablation): path costs are
  settled by the planner after the scheme's rank;
- goal persistence (A18) is the shared choice's (keep the target unless another of no worse
  rank costs under 0.8 of it), not 1.25 x U;
- the end-game safety net takes back rich waypoints (pereira_revive_min_bit) in claimed
  regions once no teammate explores, unless a teammate's place lies within revive_clear_m
  of the waypoint; the spec's subtraction of the claimants' places' cast view is not done;
  a robot that has already stopped is woken only by a retraction, not by that net;
- robots share no maps (as in the paper): a robot whose every frontier lies in regions
  teammates claimed stops, so one robot can end up exploring much longer than the rest
  (maze_a: see the commit log for figures);
- a done robot sends one done intent, not one every 30 s (the heartbeat says done);
- pushes are cancelled when the record is overheard only while they wait in the scheme's
  outbox (at most PUSH_BACKLOG on the link), there is no LinkLayer.cancel;
- routing over the region graph (it routes on its own places like the no-sharing
  baseline), the limited-range radio option (`--range-m`), the pereira-oracle,
  pereira-grid and pereira-nogossip variants, the mission's flush phase and per-robot
  digests in the JSON, the region overlay as filled areas, tests/data/pereira8, and a
  numba fold.
"""

"""Pereira, Moreira & Veloso (CONTROLO 2014): exploration by regions whose statuses robots
merge without clocks (issue 23; `../shared/schemes/pereira.md`).

NOT A SCHEME YET: nothing here is registered (firmware.schemes.SCHEMES), no node decodes
the dialect, and no mission can run it. What exists is the first two pieces of issue 23,
pure functions every robot computes alike:

    records.py   the dialect (id 3): place, gate, claim, intent, summary as fixed-size
                 records (9, 9, 10, 12, 16 B) with typed encode/decode
    gates.py     gates (doorways, corridor mouths) found in a robot's own occupancy grid,
                 their confirmation over cycles, and a place's certified free radius
    regions.py   the region graph (regions, anchors, signatures, adjacency through gates,
                 virtual regions behind gates) as a pure function of the place and gate
                 record set; claim anchors resolved to regions
    status.py    statuses as per-origin claims in a grow-only set: eq. 1 and 2, the
                 same-robot override and the loop rule, with no clock (a join)
    store.py     the records a robot holds, with the graph and the status view derived
    params.py    the parameters of all of the above (for firmware/params.py later)

Not yet: the scheme class, the explored judgement (A2), the private label grid and current
region with its margin (5.2 d, A7, A8), frontier categories and Algorithm 1 with eq. 3
(1.5, 1.6), intents and gossip (summaries and pushes, 5.5), routing over the region graph,
the limited-range radio option, the pereira-oracle variant, and a numba fold.
"""

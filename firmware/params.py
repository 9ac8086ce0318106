"""Every tunable of the explorer in one place, with units in the names.

Defaults are Bayer & Faigl's Table II, "simulated scenarios" column, unless noted.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from math import isfinite, log2

# The declaration of every parameter: its default, unit and valid range (inclusive unless
# open) and one line of meaning, in the field's metadata. `--set` checks against it,
# `--help` and the README's parameter table are generated from it (host_tools/overrides.py).
# The ranges keep values that would divide by zero, allocate absurd memory or contradict
# another parameter out; inside them the explorer runs, not necessarily well.
MAX_WINDOW_CELLS = 4000     # cells along a side of the local map's window: 64 MB of log-odds


class ParamError(ValueError):
    """A parameter value outside its declared type or range; the message names both."""


def _p(default, unit: str, lo, hi, doc: str, *, lo_open: bool = False, hi_open: bool = False):
    return field(default=default, metadata={"unit": unit, "lo": lo, "hi": hi, "lo_open": lo_open,
                                            "hi_open": hi_open, "doc": doc})


@dataclass(frozen=True)
class ExplorationParams:
    # Local dense map (Table II: resolution 10 cm, local map size d_local 20 m). The paper
    # drops points "farther than d_local from the robot", so d_local is the window's half
    # side: with a 10 m sensor and d_cam 9.5 m, a waypoint at the edge of what the robot sees
    # still has its whole d_cam disc inside the map (10 + 9.5 < 20).
    resolution_m: float = _p(0.1, 'm', 0.02, 1.0, 'cell size of the local dense map')
    d_local_m: float = _p(20.0, 'm', 2.0, 200.0, "half side of the local map's window")
    recenter_distance_m: float = _p(2.0, 'm', 0.1, 100.0,
                                    'shift the window when the robot is this far off its centre')
    # Topological map (Table II).
    d_build_m: float = _p(1.0, 'm', 0.1, 100.0, 'travel between two vertices of the topological map')
    d_connect_m: float = _p(2.5, 'm', 0.1, 100.0, 'vertices closer than this are connected')
    # Waypoints (Table II + eq. 3): information within d_cam, clusters, minimum entropy.
    d_cam_m: float = _p(9.5, 'm', 0.5, 100.0, 'radius of what a waypoint would observe')
    waypoint_cluster_radius_m: float = _p(3.0, 'm', 0.0, 100.0,
                                          'waypoint candidates within this radius form one cluster')
    # 20 bit was tried and not kept (README, "Notes and limits")
    min_cluster_entropy_bit: float = _p(90.0, 'bit', 0.0, 1e9, 'clusters holding less information are no waypoints')
    # "five artifacts of different type"
    artifact_types: int = _p(5, 'types', 1, 255, "artifact types a cell may hold (eq. 3's a)")
    candidate_spacing_m: float = _p(1.0, 'm', 0.05, 20.0, 'waypoint candidates are evaluated on this sub-grid')
    info_rays: int = _p(64, 'rays', 1, 4096, 'rays cast from a candidate to count observable cells')
    # The presence rule (schemes/bayer_faigl/presence.py): a waypoint near places teammates
    # finished with stays if this much information is out of their view (10 e_min, about
    # 3.5 m2: a room behind a door), and their view is cast with this many rays (2 pi d_cam
    # in cells: neighbouring rays one cell apart at d_cam).
    presence_keep_bit: float = _p(900.0, 'bit', 0.0, 1e9,
                                  "the presence rule keeps a waypoint with this much out of teammates' view")
    # The robot's own current target (and waypoints within the cluster radius of it) is exempt
    # from the presence rule. Off by default (README, "Notes and limits").
    presence_holds_target: bool = _p(False, 'bool', None, None,
                                     "exempt the robot's own target from the presence rule")
    # A waypoint this close to a place whose teammate reports nothing left there (e_inf 0),
    # in line of sight of it, was seen from there (PresenceRule._split_by_finished_places;
    # 0: off). 3 m, the cluster radius: well inside what the teammate's sensor saw there.
    finished_place_near_m: float = _p(3.0, 'm', 0.0, 100.0,
                                      "the presence rule drops a waypoint this close to a teammate's finished place")
    team_view_rays: int = _p(600, 'rays', 1, 20000, "rays that cast a teammate's view")
    # The presence rule's deadlock breaker (PresenceRule.revive_shared_frontiers; 0: off): a
    # teammate's place within shared_view_m of one of ours saw about what we saw from there,
    # and a waypoint that a teammate stood within revive_clear_m of was seen by it. Only
    # waypoints holding revive_min_bit (about 15 m2 unseen) are taken back: the deadlocked
    # frontier held 13146 bit, the waypoints wrongly taken back 1100 to 1500 bit (cave,
    # maze_b, Intel lab; README, "Notes and limits").
    shared_view_m: float = _p(2.5, 'm', 0.0, 100.0,
                              'deadlock breaker: a teammate place this close to ours saw what we saw')
    revive_clear_m: float = _p(3.0, 'm', 0.0, 100.0,
                               'deadlock breaker: no teammate stood this close to a waypoint it takes back')
    revive_min_bit: float = _p(4000.0, 'bit', 0.0, 1e9,
                               'deadlock breaker: information a waypoint must hold to be taken back')
    # A frontier the body cannot reach is reported (termination complete_with_unreachable_
    # frontiers) when this much unknown is in view from it: 10 e_min, about 3.5 m2, a room
    # behind a door. Less is a pocket too small to matter: under a desk, a fan of free cells
    # drawn through a chink in a wall.
    report_unreachable_bit: float = _p(900.0, 'bit', 0.0, 1e9,
                                       'a frontier the body cannot reach is reported if this much is unseen beyond it')
    # Pockets (waypoints holding less than report_unreachable_bit) are not chased across the
    # map: one is a candidate only while the robot is this close to it (straight line), so it
    # is looked into on the way past and not driven back to from the far side of the map.
    pocket_reach_m: float = _p(5.0, 'm', 0.0, 1000.0,
                               'a waypoint holding less than report_unreachable_bit is a candidate only this close')
    # Robot body and navigation.
    robot_radius_m: float = _p(0.25, 'm', 0.05, 5.0, 'robot body radius')
    # Clearance as a cost (nav2's inflation layer: lethal, then decaying). The scan fill marks
    # the cell half a cell beyond each hit, so an occupied cell holds a wall face between its
    # centre and one cell nearer the robot, half a cell on average. A cell is lethal only if
    # the body plus lethal_tolerance_m fits at none of its points (centre, side midpoints,
    # corners) with the faces where expected, or, for tight passages, at the cells' centres
    # (body_fit.PlanningFits).
    lethal_tolerance_m: float = _p(0.02, 'm', 0.0, 0.03, 'the body plus this must fit where a path goes')
    # Ordinary plans also pass where the body plus lethal_tolerance_m fits only with the faces
    # at their cells' centres (body_fit.PlanningFits), at this many times the cost: a door the
    # raster shows barely wider than the body is a way on, taken where nothing wider is near.
    tight_passage_cost: float = _p(10.0, '1', 0.0, 1e6,
                                   "cost factor of passages the body fits only with walls at their cells' centres "
                                   "(0: ordinary plans never take them)")
    inflation_radius_m: float = _p(1.0, 'm', 0.0, 50.0, 'paths pay extra closer than this to walls or unknown')
    inflation_cost_weight: float = _p(2.0, '1', 0.0, 1000.0, 'extra cost factor right at the body, decaying outwards')
    inflation_decay_per_m: float = _p(3.0, '1/m', 0.0, 100.0, "how fast that extra cost decays with distance")
    waypoint_reached_m: float = _p(0.5, 'm', 0.05, 50.0, 'a target this close is reached')
    # A target whose information the robot saw while this close to it counts as reached
    # (TargetKeeper.end_if_seen_on_way) and is banned: a few wall cells turning unknown again
    # can otherwise make a waypoint there again and again. Farther off, it merely expires.
    # 0: off, the default. With 1.5 m (commit 3f50bfa) one robot on the Intel lab drove 409 m
    # instead of 1398 m but covered 0.9893 instead of 0.9912, below issue 2's 0.99.
    target_seen_within_m: float = _p(0.0, 'm', 0.0, 50.0,
                                     'a target whose information was seen from this close counts as reached (0: off)')
    # The path follower slows down and looks less far ahead where the path leaves less room
    # than this beside the body, down to min_speed_mps.
    slow_clearance_m: float = _p(0.25, 'm', 0.0, 10.0,
                                 'room beside the body below which the robot slows down and steers closely')
    min_speed_mps: float = _p(0.1, 'm/s', 0.01, 10.0, 'the slowest the robot drives a path')
    # Recovery (services.recovery): before a target is struck or dropped, back off this far
    # if the LiDAR shows room behind, turn once on the spot at this rate, then retry on a
    # tighter, slower path (wall faces at their cells' centres everywhere, tight passages at no
    # extra cost, min_speed_mps) this long.
    recovery_back_off_m: float = _p(0.3, 'm', 0.0, 5.0, 'a recovery backs off this far if there is room behind')
    recovery_turn_radps: float = _p(0.8, 'rad/s', 0.05, 10.0, 'a recovery turns once on the spot at this rate')
    recovery_retry_s: float = _p(20.0, 's', 0.0, 3600.0, 'after a recovery, plans are tight and slow for this long')
    # A robot about to stop whose map closed a way it drove, with frontiers beyond, drives
    # back along its trail across the closure first (Planner._way_back): at most this many
    # times in a mission, successful or not, so that a robot walled in by its own map tries
    # a few ways out and then stops.
    ways_back_max: int = _p(3, 'drives', 0, 1000, 'drives back across a way the map closed, per mission')
    lookahead_m: float = _p(0.35, 'm', 0.05, 50.0, "path follower's lookahead")
    rotate_in_place_rad: float = _p(0.8, 'rad', 0.0, 3.1416,
                                    'heading error above which the robot turns on the spot')
    heading_gain: float = _p(2.0, '1/s', 0.0, 100.0, 'turn rate per radian of heading error')
    # A waypoint that was reached or proved unreachable is dropped for good; candidates this
    # close to it are never generated again, which bounds the mission (finite area).
    ban_radius_m: float = _p(1.5, 'm', 0.0, 50.0, 'no candidates this close to a dropped waypoint')
    unreachable_strikes: int = _p(3, 'cycles', 1, 10000,
                                  'planning cycles without a route before a waypoint is dropped')
    # ... counted at most this often (the planning period)
    unreachable_strike_interval_s: float = _p(1.0, 's', 0.0, 3600.0, 'strikes are counted at most this often')
    escape_radius_m: float = _p(0.8, 'm', 0.0, 50.0, 'how far to look for a traversable cell to start from')
    # Scan-to-map matching (services.scan_match): every scan_match_every_m of travel or
    # scan_match_every_rad of turning, the scan is matched to the map on a grid of poses
    # around odometry's, scan_match_step_m / _rad apart out to scan_match_search_m / _rad.
    # Odometry drifts a few millimetres between two matches; a cell is 0.1 m. Off by default
    # until the team grid has run with it: one robot on Willow Garage reaches 0.99 coverage in
    # 8 of 10 runs with it and 5 without (commit 7712e84), but where the map was bent on an
    # earlier pass it holds the robot to the bend (README, "Navigation through narrow doors").
    scan_match: bool = _p(False, 'bool', None, None, 'correct the odometry by matching scans to the map')
    scan_match_every_m: float = _p(0.25, 'm', 0.0, 100.0, 'a scan is matched after this much travel')
    scan_match_every_rad: float = _p(0.1, 'rad', 0.0, 6.3, '... or this much turning')
    scan_match_search_m: float = _p(0.1, 'm', 0.0, 2.0, 'scan matching searches this far from odometry, each way')
    scan_match_step_m: float = _p(0.025, 'm', 0.001, 1.0, 'scan matching tries positions this far apart')
    scan_match_search_rad: float = _p(0.02, 'rad', 0.0, 0.5, 'scan matching searches this far in heading, each way')
    scan_match_step_rad: float = _p(0.005, 'rad', 0.0001, 0.5, 'scan matching tries headings this far apart')
    scan_match_min_gain: float = _p(0.002, 'score', 0.0, 1.0,
                                    'a correction must fit the scan this much better than odometry (mean wall likelihood)')
    # The whole map (services.known_map: the window and every paged-out tile) routes to places the
    # window and the graph cannot, and finds what is left before a robot stops; it is derived
    # again when older than this or once the robot has moved recenter_distance_m.
    known_map_refresh_s: float = _p(10.0, 's', 0.0, 3600.0, 'the whole map is derived again when this old')
    stuck_after_s: float = _p(0.5, 's', 0.0, 3600.0, 'driving without moving this long marks an obstacle (0: off)')
    # ... or, wheels slipping: the LiDAR does not see the travel odometry counts (motion.StallDetector).
    slip_check_m: float = _p(0.05, 'm', 0.0, 10.0, 'odometry travel the LiDAR must see about half of (0: off)')
    # After a stall the robot first backs off this far (if the LiDAR shows room behind), so it
    # does not keep pressing on what holds it while it plans again.
    stall_back_off_m: float = _p(0.1, 'm', 0.0, 1.0, 'after a stall, back off this far if there is room behind')
    # Without that room (a body wedged between furniture, touching on both sides, reads no
    # room in any straight line), it drives back this far along the way it came by odometry
    # (services.recovery.Retrace): the body was there a moment ago, so it fits.
    stall_retrace_m: float = _p(0.5, 'm', 0.0, 5.0,
                                'after a stall with no room straight behind, drive back this far the way it came (0: off)')
    # ... then, if the LiDAR shows what held it, path points are not cut this far
    follow_closely_after_stall_m: float = _p(1.0, 'm', 0.0, 50.0, 'after a stall, path points are not cut this far')
    stall_timeout_s: float = _p(20.0, 's', 0.1, 86400.0, 'no progress towards the target for this long drops it')
    # Log-odds occupancy update.
    logodds_hit: float = _p(1.2, 'log-odds', 0.0, 100.0, 'added to a cell a beam ends in', lo_open=True)
    logodds_miss: float = _p(-0.4, 'log-odds', -100.0, 0.0, 'added to a cell a beam passes', hi_open=True)
    logodds_min: float = _p(-4.0, 'log-odds', -1000.0, 0.0, "lower clamp of a cell's log-odds", hi_open=True)
    logodds_max: float = _p(4.0, 'log-odds', 0.0, 1000.0, "upper clamp of a cell's log-odds", lo_open=True)
    logodds_occupied: float = _p(0.3, 'log-odds', -1000.0, 1000.0, 'a cell above this is occupied')
    logodds_free: float = _p(-0.3, 'log-odds', -1000.0, 1000.0, 'a cell below this is free')
    # Keyframes (the dense baselines' map updates): the scan at each topological vertex,
    # binned to this many bearings, sent to every teammate on the mesh link.
    keyframe_bins: int = _p(360, 'bearings', 8, 3600, "bearings a dense baseline's keyframe scan is binned to")
    # Meier et al. (firmware.schemes.meier; ../shared/schemes/meier.md sections 2 and 4). The
    # polygons are refined by at most meier_split_rate_hz edge splits a second (the paper's
    # split rate, a token bucket), while fewer than meier_backlog_max of their records wait
    # on the link, to meier_eps_m (one lattice cell: zero error is a vertex at every
    # staircase step). Eq. (1) uses the LiDAR's range; beta prices a metre of path against
    # utility (1 / range: a goal 1 m farther from a claimed target gains what 1 m of travel
    # costs).
    meier_split_rate_hz: float = _p(1.0, 'splits/s', 0.0, 1000.0, 'edge splits a second at most (the split rate)')
    meier_eps_m: float = _p(0.2, 'm', 0.0, 10.0, 'polygons are refined until no boundary point is farther from its edge')
    meier_update_s: float = _p(1.0, 's', 0.05, 3600.0, 'the polygons follow the map this often')
    # A3 of meier.md: a crack or two of one type amid the other is a missed beam or a speck,
    # and each type change is a vertex that stays while its corner is on the boundary
    # (maze_a seed 0 over eu868-g3: 3 cut LoRa bytes 19 %, approximation error 0.074 -> 0.045).
    meier_type_min_run: int = _p(3, 'cracks', 1, 100,
                                 'a run of boundary cracks of one type shorter than this takes the type around it')
    # A junction of wall and frontier that advances along a wall with the frontier would
    # leave a vertex at every update (vertices never move): held on a vertex this far back,
    # the wall between drawn as frontier, it leaves one every this far.
    meier_junction_hold_m: float = _p(2.0, 'm', 0.0, 100.0,
                                      'a wall/frontier junction stays on a vertex at most this far back along the wall')
    # The split rate from the radio's budget (issue 22): a robot's traffic (every frame it
    # sends: polygon records, targets, heartbeats, headers) may use this share of the bytes
    # a second its link can sustain (duty cycle, byte-rate cap), on average; edge splits,
    # up to the split rate, take only what the rest leaves, and while the robot is over it
    # the polygons do not follow the map at all (the forced updates wait, at most the ten
    # seconds the budget saves up). 0.4 of eu868-g3's 64 B/s is 25.6 B/s: what the budget
    # does not hold back (repairs, summaries, targets) stays under issue 22's 30.
    meier_radio_share: float = _p(0.4, 'share', 0.0, 1.0, "share of the link's sustained byte rate a robot's "
                                  "traffic may use before its polygons wait", lo_open=True)
    meier_backlog_max: int = _p(8, 'records', 1, 64, 'no splits while this many polygon records wait on the link')
    # Lost frames are asked for by number (poly_nack) within the link's 64-frame window;
    # beyond it (a long spell out of range, a request lost, a sender that fell silent) a
    # receiver finds what it lacks from the sender's block summaries (poly_sum, 16 bytes).
    meier_sum_period_s: float = _p(5.0, 's', 0.1, 3600.0, 'a summary of one block of the own vertex ids goes this '
                                   'often while nothing else of the polygons waits')
    meier_max_range_m: float = _p(10.0, 'm', 0.1, 1000.0, "the sensor's range in eq. (1)", lo_open=True)
    meier_beta_per_m: float = _p(0.1, '1/m', 0.0, 100.0, 'utility a metre of path costs (Algorithm 1)', lo_open=True)
    meier_discount_all: bool = _p(False, 'bool', None, None, "discount every teammate's target, not only lower ids'")
    meier_target_move_m: float = _p(1.0, 'm', 0.0, 100.0, 'a new target record when the target moves this far')
    meier_target_keepalive_s: float = _p(30.0, 's', 1.0, 3600.0, 'the target record is repeated this often')
    meier_team_extent_m: float = _p(100.0, 'm', 10.0, 1000.0, "teammates' polygons are drawn this far around the robot")
    meier_min_hole_m2: float = _p(0.5, 'm^2', 0.0, 100.0, 'holes in the own map smaller than this get no ring (not sent)')
    meier_target_expiry_s: float = _p(90.0, 's', 1.0, 36000.0, "a teammate's target is forgotten this long after its record")
    # Pereira et al. (firmware.schemes.pereira; ../shared/schemes/pereira.md sections 2, 4 and
    # 5). The gate detector's and the fold's geometry stay in firmware/schemes/pereira/params.py:
    # every robot must fold the same records into the same regions, so they are part of the
    # dialect's meaning, not a robot's tuning; the widening ratio is the one tuning knob the
    # spec names (section 7: 0.7 against over-segmentation).
    pereira_margin_m: float = _p(1.0, 'm', 0.0, 50.0,
                                 'the current region changes after this much travel in another (hysteresis)')
    pereira_label_reach_m: float = _p(10.0, 'm', 0.5, 100.0,
                                      'a waypoint is in the region of the nearest place this close, no gate between')
    # Places go every d_build_m (the spec's d_place); with this > 0 none where the region graph
    # holds a place that close (fewer bytes, fewer signature changes undoing claims). Off by
    # default: measured on two seeds per map only (docs/pereira/claims-near-only/).
    pereira_place_skip_m: float = _p(0.0, 'm', 0.0, 5.0,
                                     "no place is sent where the region graph holds one this close (0: a place "
                                     "every d_build_m)")
    pereira_explored_cycles: int = _p(2, 'cycles', 1, 100,
                                      'planning cycles in a row a region must look explored before it is claimed')
    pereira_intent_period_s: float = _p(5.0, 's', 0.5, 3600.0, 'the intent record is repeated this often')
    pereira_intent_move_m: float = _p(1.0, 'm', 0.0, 100.0, 'a new intent record when the goal moves this far')
    pereira_intent_expiry_s: float = _p(15.0, 's', 1.0, 36000.0,
                                        "a teammate's intent is ignored this long after its record")
    pereira_summary_period_s: float = _p(10.0, 's', 1.0, 3600.0, 'a summary of the records held is sent this often')
    pereira_push_max: int = _p(6, 'records', 0, 64,
                               "records pushed per lagging origin and summary heard (0: no gossip)")
    pereira_gate_period_s: float = _p(2.0, 's', 0.1, 3600.0, "gates are looked for in the robot's map this often")
    pereira_widening_kappa: float = _p(0.5, '1', 0.0, 10.0,
                                       'a gate needs free space (1 + this) times its clearance wide beyond it')
    # The spec's end-game safety net while teammates explore, off by default: with transit
    # and the teammates' view no run needed it (five robots on maze_a and the cave, two and
    # three on the eight-region map: coverage >= 0.996 without), and on maze_a the last robot
    # exploring drove on for minutes taking back waypoints whose promise was the far rim of
    # its own map (p_max 539 m with it, 333 m without; docs/pereira/transit-5651009/).
    pereira_take_back: bool = _p(False, 'bool', None, None,
                                 "a robot with nothing else left takes back waypoints in regions others claimed "
                                 "that their places could not have seen")
    # The same net for the last robot exploring only, off by default. Without it and without
    # pereira_claims_near_only, a room no one entered, labelled into a claimed region through
    # a doorway no gate marks, was left unseen (maze_b seed 5: coverage 0.80); with it the
    # room is covered, but on maze_a's ten seeds the last robot retraced its teammates'
    # regions: p_max 559 m against 331 (docs/pereira/take-back-alone/).
    pereira_take_back_alone: bool = _p(False, 'bool', None, None,
                                       "with no teammate exploring any more, a robot takes back waypoints in regions "
                                       "others claimed that their places could not have seen")
    pereira_revive_min_bit: float = _p(4000.0, 'bit', 0.0, 1e9,
                                       "waypoints this rich in regions others claimed are taken back by a robot "
                                       "with nothing else left and no teammate's region to head for, or with no "
                                       "teammate exploring")
    pereira_revive_left_bit: float = _p(900.0, 'bit', 0.0, 1e9,
                                        "... if this much is left unseen by a LiDAR at every teammate's place")
    # A claim covers its region as its claimant knew it; this robot's label grid may carry the
    # region's label through a doorway no gate marks into rooms no teammate came near. Their
    # waypoints are kept, not left to the claim (maze_b seed 5 without: coverage 0.80, every
    # robot stopped by itself; docs/pereira/claims-near-only/).
    pereira_claims_near_only: bool = _p(True, 'bool', None, None,
                                        "a waypoint in a region others claimed is left to them only if a "
                                        "teammate's place lies within d_cam_m of it")
    # ... and ranked after every other: a robot goes there once nothing else is left, when a
    # teammate may have come near (then they are left to the claim after all). maze_b seed 5:
    # p_max 338 m ranked last, 587 m ranked by their category.
    pereira_unseen_claimed_last: bool = _p(True, 'bool', None, None,
                                           "those waypoints are ranked after every other")
    # Waypoints in regions no one claimed are dropped when the teammates' places saw what they
    # promise (the take-back's test): claims come late, or never for a region explored in parts.
    pereira_team_view: bool = _p(True, 'bool', None, None,
                                 "waypoints in unclaimed regions that teammates' places saw are dropped")
    # A teammate's place sees its own side of a gate: the view's rays pass through what this
    # robot's map shows unknown, walls it never saw included, so without this a teammate in a
    # corridor "sees" the rooms off it (the Intel lab: docs/pereira/intel-gates/).
    pereira_gates_block_view: bool = _p(True, 'bool', None, None,
                                        "the teammates' places' view stops at gates")
    # A robot with nothing else left heads for the regions teammates are heading for, along
    # the places they left (the region graph's edges), instead of stopping while they work on.
    pereira_transit: bool = _p(True, 'bool', None, None,
                               "with nothing else left, drive towards regions teammates are heading for, along "
                               "their places")
    pereira_transit_new_m: float = _p(3.0, 'm', 0.1, 100.0,
                                      "... to teammates' places at least this far from every place of the robot's own")
    # Within a category the spec's A9 orders by U = e_bit / (cost_m + pereira_cost_offset_m):
    # the paper weighs "size of frontier and cost" with no formula; the offset keeps a waypoint
    # under the robot from outweighing every other. pereira_by_cost=true orders by cost alone,
    # the spec's plain-distance ablation (pereira_order=cost).
    pereira_cost_offset_m: float = _p(1.0, 'm', 0.0, 100.0,
                                      "within a category, waypoints are ordered by e_bit / (cost + this)")
    pereira_by_cost: bool = _p(False, 'bool', None, None,
                               'within a category, the cheapest waypoint first (the ablation of the spec)')
    @property
    def entropy_per_cell_bit(self) -> float:
        """log2(a + 1): one cell's prior entropy over 'no artifact or one of a types' (eq. 3)."""
        return log2(self.artifact_types + 1)

    @property
    def window_cells(self) -> int:
        return int(round(2 * self.d_local_m / self.resolution_m))


_FIELDS = {f.name: f for f in fields(ExplorationParams)}


def param_kind(name: str) -> str:
    """'bool', 'int' or 'float': the annotation of an ExplorationParams field."""
    return _FIELDS[name].type


def param_range(name: str) -> str:
    """The valid range of a parameter as text, e.g. '0.02 <= resolution_m <= 1 m'."""
    f = _FIELDS[name]
    m = f.metadata
    if f.type == "bool":
        return f"{name} is true or false"
    lo = f"{m['lo']:g} {'<' if m['lo_open'] else '<='} "
    hi = f" {'<' if m['hi_open'] else '<='} {m['hi']:g}"
    unit = "" if m["unit"] in ("", "1") else f" {m['unit']}"
    return f"{lo}{name}{hi}{unit}"


def check_param(name: str, value) -> None:
    """ParamError naming the parameter, the value and the valid range, unless `value` is of
    the parameter's type and within its range."""
    if name not in _FIELDS:
        raise ParamError(f"no explorer parameter {name!r}")
    f = _FIELDS[name]
    m = f.metadata
    kinds = {"bool": (bool,), "int": (int,), "float": (int, float)}[f.type]
    if not isinstance(value, kinds) or (f.type != "bool" and isinstance(value, bool)):
        raise ParamError(f"{name} = {value!r}: takes a {f.type} ({param_range(name)})")
    if f.type == "bool":
        return
    below = value <= m["lo"] if m["lo_open"] else value < m["lo"]
    above = value >= m["hi"] if m["hi_open"] else value > m["hi"]
    if not isfinite(value) or below or above:
        raise ParamError(f"{name} = {value!r} is outside the valid range {param_range(name)}")


def check_params(p: "ExplorationParams") -> None:
    """Every parameter within its range, and the relations between them: the local map's
    window at most MAX_WINDOW_CELLS a side, the log-odds thresholds between the clamps, a
    tight passage's cost factor 0 or at least 1.
    Raises ParamError naming the parameters, their values and what must hold."""
    for f in fields(p):
        check_param(f.name, getattr(p, f.name))
    cells = 2 * p.d_local_m / p.resolution_m
    if cells > MAX_WINDOW_CELLS:
        raise ParamError(
            f"d_local_m = {p.d_local_m:g} with resolution_m = {p.resolution_m:g} makes a local map window of "
            f"{cells:.0f} x {cells:.0f} cells ({4 * cells * cells / 2**20:.0f} MiB of log-odds); at most "
            f"{MAX_WINDOW_CELLS} a side: raise resolution_m to at least {2 * p.d_local_m / MAX_WINDOW_CELLS:g} m")
    if p.recenter_distance_m >= p.d_local_m:
        raise ParamError(f"recenter_distance_m = {p.recenter_distance_m:g} must be below d_local_m = "
                         f"{p.d_local_m:g} (the window moves before the robot leaves it)")
    if 0.0 < p.tight_passage_cost < 1.0:
        raise ParamError(f"tight_passage_cost = {p.tight_passage_cost:g} must be 0 (no tight passages in ordinary "
                         "plans) or at least 1 (a passage never costs less than open floor)")
    chain = [("logodds_min", p.logodds_min), ("logodds_free", p.logodds_free),
             ("logodds_occupied", p.logodds_occupied), ("logodds_max", p.logodds_max)]
    for (a, va), (b, vb) in zip(chain, chain[1:]):
        if not va < vb:
            raise ParamError(f"{a} = {va:g} must be below {b} = {vb:g} "
                             "(logodds_min < logodds_free < logodds_occupied < logodds_max)")


@dataclass(frozen=True)
class TaskRates:
    """The fixed task table's rates. The tick period is the fastest rate's period."""

    lidar_hz: float = 10.0
    control_hz: float = 20.0
    planning_hz: float = 1.0
    radio_hz: float = 20.0
    # The core heartbeat (where a robot is, whether it is done), for every scheme that talks:
    # a 12-byte record every 10 s is 1.2 B/s, well inside the 2.9 B/s that one robot may send
    # in the EU 1 % sub-band (SF7, 12-byte frames); aggregated with other records it costs
    # less. A teammate not heard of for 3 periods counts as gone.
    heartbeat_hz: float = 0.1
    heartbeats_to_age_out: int = 3

    @property
    def roster_max_age_us(self) -> int:
        return int(round(self.heartbeats_to_age_out * 1_000_000 / self.heartbeat_hz))

    @property
    def tick_period_us(self) -> int:
        return int(round(1_000_000 / max(self.lidar_hz, self.control_hz, self.planning_hz, self.radio_hz)))

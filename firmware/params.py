"""Every tunable of the explorer in one place, with units in the names.

Defaults are Bayer & Faigl's Table II, "simulated scenarios" column, unless noted.
"""
from __future__ import annotations

from dataclasses import dataclass
from math import log2


@dataclass(frozen=True)
class ExplorationParams:
    # Local dense map (Table II: resolution 10 cm, local map size d_local 20 m). The paper
    # drops points "farther than d_local from the robot", so d_local is the window's half
    # side: with a 10 m sensor and d_cam 9.5 m, a waypoint at the edge of what the robot sees
    # still has its whole d_cam disc inside the map (10 + 9.5 < 20).
    resolution_m: float = 0.1
    d_local_m: float = 20.0
    recenter_distance_m: float = 2.0        # shift the window when the robot is this far off centre
    # Topological map (Table II).
    d_build_m: float = 1.0
    d_connect_m: float = 2.5
    # Waypoints (Table II + eq. 3): information within d_cam, clusters, minimum entropy.
    d_cam_m: float = 9.5
    waypoint_cluster_radius_m: float = 3.0
    min_cluster_entropy_bit: float = 90.0    # 20 bit was tried and not kept (README, "Notes and limits")
    artifact_types: int = 5                  # "five artifacts of different type"
    candidate_spacing_m: float = 1.0         # waypoint candidates are evaluated on this sub-grid
    info_rays: int = 64                      # rays cast from a candidate to count observable cells
    # The presence rule (Explorer._drop_waypoints_seen_by_others): a waypoint near places
    # teammates finished with stays if this much information is out of their view (10 e_min,
    # about 3.5 m2: a room behind a door), and their view is cast with this many rays
    # (2 pi d_cam in cells: neighbouring rays one cell apart at d_cam).
    presence_keep_bit: float = 900.0
    # The robot's own current target (and waypoints within the cluster radius of it) is exempt
    # from the presence rule. Off by default (README, "Notes and limits").
    presence_holds_target: bool = False
    team_view_rays: int = 600
    # The presence rule's deadlock breaker (Explorer._revive_shared_frontiers; 0: off): a
    # teammate's place within shared_view_m of one of ours saw about what we saw from there,
    # and a waypoint that a teammate stood within revive_clear_m of was seen by it. Only
    # waypoints holding revive_min_bit (about 15 m2 unseen) are taken back: the deadlocked
    # frontier held 13146 bit, the waypoints wrongly taken back 1100 to 1500 bit (cave,
    # maze_b, Intel lab; README, "Notes and limits").
    shared_view_m: float = 2.5
    revive_clear_m: float = 3.0
    revive_min_bit: float = 4000.0
    # Robot body and navigation.
    robot_radius_m: float = 0.25
    safety_margin_m: float = 0.07            # traversable cells keep radius + margin from walls
    clearance_cost_m: float = 1.0            # below this distance to walls/unknown, paths pay extra
    clearance_cost_weight: float = 2.0
    waypoint_reached_m: float = 0.5
    # A target whose information the robot saw while this close to it counts as reached
    # (Explorer.plan) and is banned: a few wall cells turning unknown again can otherwise
    # make a waypoint there again and again. Farther off, it merely expires, as any does.
    # 0: off, the default. With 1.5 m (commit 3f50bfa) one robot on the Intel lab drove 409 m
    # instead of 1398 m but covered 0.9893 instead of 0.9912, below issue 2's 0.99.
    target_seen_within_m: float = 0.0
    lookahead_m: float = 0.35
    rotate_in_place_rad: float = 0.8
    heading_gain: float = 2.0
    # A waypoint that was reached or proved unreachable is dropped for good; candidates this
    # close to it are never generated again, which bounds the mission (finite area).
    ban_radius_m: float = 1.5
    unreachable_strikes: int = 3             # planning cycles in a row without a route before a drop
    unreachable_strike_interval_s: float = 1.0   # ... counted at most this often (the planning period)
    escape_radius_m: float = 0.8             # how far to look for a traversable cell to start from
    stuck_after_s: float = 0.5               # driving without moving this long marks an obstacle (0: off)
    follow_closely_after_stall_m: float = 1.0   # ... or, if the LiDAR shows it, path points are not cut this far
    stall_timeout_s: float = 20.0            # no progress towards the target for this long: drop it
    # Log-odds occupancy update.
    logodds_hit: float = 1.2
    logodds_miss: float = -0.4
    logodds_min: float = -4.0
    logodds_max: float = 4.0
    logodds_occupied: float = 0.3
    logodds_free: float = -0.3
    # Keyframes (the dense baselines' map updates): the scan at each topological vertex,
    # binned to this many bearings, sent to every teammate on the mesh link.
    keyframe_bins: int = 360

    @property
    def entropy_per_cell_bit(self) -> float:
        """log2(a + 1): one cell's prior entropy over 'no artifact or one of a types' (eq. 3)."""
        return log2(self.artifact_types + 1)

    @property
    def window_cells(self) -> int:
        return int(round(2 * self.d_local_m / self.resolution_m))


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

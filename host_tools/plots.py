"""PNG figures of missions: ground truth, what the team observed, paths, topological maps."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

ROBOT_COLOURS = plt.get_cmap("tab10").colors
# Beyond this many robots the colours repeat and a legend entry per robot would bury the map:
# the figure names the team's range instead.
MAX_LEGEND_ROBOTS = len(ROBOT_COLOURS)


def _legend(ax, robots: int, fontsize: int) -> None:
    """A legend entry per robot, when there are few enough to tell apart."""
    if robots <= MAX_LEGEND_ROBOTS and ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=fontsize)


def _background(ax, occ, observed=None) -> None:
    """Walls dark, free space white, observed free space tinted."""
    img = np.where(occ.free, 1.0, 0.15)
    rgb = np.dstack([img, img, img])
    if observed is not None:
        seen = observed & occ.free
        rgb[seen] = (0.80, 0.92, 0.80)
    extent = (occ.origin_x_m, occ.origin_x_m + occ.width_m, occ.origin_y_m, occ.origin_y_m + occ.height_m)
    ax.imshow(rgb, origin="lower", extent=extent, interpolation="nearest")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")


def plot_mission(result, path: Path) -> None:
    world = result.world
    occ = world.occ
    fig, axes = plt.subplots(1, 2, figsize=(14, 7), constrained_layout=True)
    ax = axes[0]
    _background(ax, occ, world.observed_union())
    for i, t in enumerate(result.trajectories):
        c = ROBOT_COLOURS[i % len(ROBOT_COLOURS)]
        ax.plot(t[:, 0], t[:, 1], color=c, lw=1.0, label=f"robot {i}: {result.path_length_m[i]:.0f} m")
        ax.plot(t[0, 0], t[0, 1], "o", color=c, ms=5)
    team = "" if len(result.trajectories) <= MAX_LEGEND_ROBOTS else \
        f"\n{len(result.trajectories)} robots, paths {min(result.path_length_m):.0f} to {max(result.path_length_m):.0f} m"
    ax.set_title(f"{result.map_label}: observed {result.coverage * 100:.1f} % of reachable free area, "
                 f"T_total {result.t_total_s:.0f} s ({result.termination}){team}", fontsize=10)
    _legend(ax, len(result.trajectories), 8)
    ax = axes[1]
    _background(ax, occ)
    title = "what the robots' scheme shares: nothing"
    for i, agent in enumerate(result.agents):
        c = ROBOT_COLOURS[i % len(ROBOT_COLOURS)]
        geometry = agent.scheme.drawables()
        if not geometry:
            continue
        title = geometry.get("title", title)
        xy = np.asarray(geometry.get("points", np.zeros((0, 2)))).reshape(-1, 2)
        segments = np.asarray(geometry.get("segments", np.zeros((0, 2, 2)))).reshape(-1, 2, 2)
        if result.config.frames == "own" and i < len(result.start_poses):
            # Each robot draws in its own frame: the host alone knows where that lies (its start pose).
            xy, segments = _to_world(xy, result.start_poses[i]), _to_world(segments, result.start_poses[i])
        if "regions" in geometry:
            # A partition every robot derives alike from the records it holds: the first
            # robot's stands for the team's (the report's scheme digests say whether they agree).
            if i == 0:
                _draw_regions(ax, xy, segments, np.asarray(geometry["regions"]), geometry.get("what", "points"))
            continue
        ax.add_collection(LineCollection(segments, colors=[c], linewidths=0.5, alpha=0.6))
        if len(xy):
            ax.scatter(xy[:, 0], xy[:, 1], s=4, color=c, label=f"robot {i}: {len(xy)} {geometry.get('what', 'points')}")
            marked = np.asarray(geometry.get("highlight", np.zeros(len(xy), bool)), bool)
            ax.scatter(xy[marked, 0], xy[marked, 1], s=14, facecolors="none", edgecolors="red", lw=0.5)
    if result.config.frames == "own":
        title += ",\neach robot's map placed by its true start pose (known to the host only)"
    ax.set_title(title, fontsize=10)
    _legend(ax, len(result.agents), 8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _draw_regions(ax, xy: np.ndarray, segments: np.ndarray, regions: np.ndarray, what: str) -> None:
    """Points coloured by the region they belong to (colours cycle), the cuts between
    regions as black segments."""
    tab20 = np.asarray(plt.get_cmap("tab20").colors)
    palette = np.concatenate([tab20[0::2], tab20[1::2]])     # dark hues first: neighbours' colours differ more
    ax.add_collection(LineCollection(segments, colors="black", linewidths=1.5))
    if len(xy):
        ax.scatter(xy[:, 0], xy[:, 1], s=6, c=palette[regions % len(palette)],
                   label=f"robot 0: {len(xy)} {what} in {len(np.unique(regions))} regions")


def _to_world(xy: np.ndarray, pose) -> np.ndarray:
    """Points (..., 2) in a robot's own odometry frame, in the world's, its start pose given."""
    x0, y0, yaw = pose
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.empty_like(np.asarray(xy, np.float64))
    out[..., 0] = c * xy[..., 0] - s * xy[..., 1] + x0
    out[..., 1] = s * xy[..., 0] + c * xy[..., 1] + y0
    return out


def _draw_paths(ax, occ, trial: dict, legend: bool) -> None:
    _background(ax, occ)
    for i, xy in enumerate(trial.get("paths_xy", [])):     # none kept: the map alone
        xy = np.asarray(xy).reshape(-1, 2)
        c = ROBOT_COLOURS[i % len(ROBOT_COLOURS)]
        ax.plot(xy[:, 0], xy[:, 1], color=c, lw=1.0 if legend else 0.6,
                label=f"robot {i}: {trial['path_length_m'][i]:.0f} m")
        if len(xy):
            ax.plot(xy[0, 0], xy[0, 1], "o", color=c, ms=4 if legend else 2)
    if legend:
        _legend(ax, len(trial.get("paths_xy", [])), 7)


def plot_sweep_paths(occ, label: str, trial: dict, path: Path) -> None:
    """Every robot's path in one trial of a sweep (Bayer & Faigl Figs. 8 and 9)."""
    fig, ax = plt.subplots(figsize=(7, 7), constrained_layout=True)
    _draw_paths(ax, occ, trial, legend=True)
    ax.set_title(f"{label}, {trial['strategy']}, seed {trial['seed']}: longest path "
                 f"{max(trial['path_length_m']):.0f} m, coverage {trial['coverage'] * 100:.1f} %", fontsize=9)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_sweep_overview(rows: list[tuple], path: Path) -> None:
    """One panel per map (rows of (occ, label, one trial per strategy)) and strategy
    (columns) with every robot's path, so the strategies can be compared at a glance."""
    columns = max(len(trials) for _, _, trials in rows)
    fig, axes = plt.subplots(len(rows), columns, figsize=(3.2 * columns, 3.2 * len(rows)),
                             constrained_layout=True, squeeze=False)
    for r, (occ, label, trials) in enumerate(rows):
        for c, trial in enumerate(trials):
            ax = axes[r][c]
            _draw_paths(ax, occ, trial, legend=False)
            ax.set_title(f"{label}, {trial['strategy']}, seed {trial['seed']}\nlongest "
                         f"{max(trial['path_length_m']):.0f} m, coverage {trial['coverage'] * 100:.1f} %", fontsize=8)
            ax.set_xlabel("")
            ax.set_ylabel("")
            ax.tick_params(labelsize=6)
    fig.savefig(path, dpi=80)
    plt.close(fig)


def plot_sweep_p_max(labels: list[str], strategies: list[str], longest: list[dict], radio: str, path: Path) -> None:
    """The longest robot path of every trial, one dot per seed, per map (labels[i], with
    longest[i][strategy] the values) and strategy, with the median (p_max) as a bar: how far
    apart single trials lie next to the medians compared."""
    fig, axes = plt.subplots(1, len(labels), figsize=(3.6 * len(labels), 3.6), constrained_layout=True,
                             squeeze=False)
    for ax, label, by_strategy in zip(axes[0], labels, longest):
        for k, s in enumerate(strategies):
            values = np.asarray(by_strategy.get(s, []), dtype=float)
            if not len(values):
                continue
            ax.plot(np.full(len(values), k) + np.linspace(-0.15, 0.15, len(values)), values, "o",
                    color=ROBOT_COLOURS[k % len(ROBOT_COLOURS)], ms=3, alpha=0.8)
            ax.plot([k - 0.3, k + 0.3], [np.median(values)] * 2, color="black", lw=1.5)
        ax.set_xticks(range(len(strategies)))
        ax.set_xticklabels(strategies, rotation=30, ha="right", fontsize=8)
        ax.set_title(label, fontsize=9)
        ax.set_ylabel("longest robot path [m]")
        ax.set_ylim(bottom=0)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle(f"every trial's longest path (dots) and the median, p_max (bars); radio {radio}", fontsize=9)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_unobservable(occ, drivable: np.ndarray, unseen: np.ndarray, title: str, path: Path) -> None:
    """Where a planner with some clearance can stand (tinted) and the reachable cells its
    LiDAR sees from none of those places (red): `lorascout map`."""
    fig, ax = plt.subplots(figsize=(8, 8), constrained_layout=True)
    _background(ax, occ, drivable)
    red = np.zeros(unseen.shape + (4,))
    red[unseen] = (0.85, 0.0, 0.0, 1.0)
    extent = (occ.origin_x_m, occ.origin_x_m + occ.width_m, occ.origin_y_m, occ.origin_y_m + occ.height_m)
    ax.imshow(red, origin="lower", extent=extent, interpolation="nearest")
    ax.set_title(title, fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)

"""Mission figures stay readable whatever the team's size."""
import numpy as np
from PIL import Image

from host_tools.mission import MissionConfig, run_mission
from host_tools.plots import plot_mission


def _wall_share(png) -> float:
    """Share of the figure's pixels in the walls' dark grey: how much of it is map."""
    rgb = np.asarray(Image.open(png).convert("RGB"), np.int16)
    return float((np.abs(rgb - round(0.15 * 255)).max(axis=2) <= 2).mean())


def test_a_large_team_leaves_the_map_its_room(tmp_path):
    """Forty robots are more than the palette tells apart: no legend entry per robot, so
    the map keeps the room a team of three has."""
    shares = []
    for robots in (3, 40):
        result = run_mission(MissionConfig(map_spec="cave:1:60x60", robots=robots, seed=0, max_sim_s=2))
        plot_mission(result, tmp_path / f"{robots}.png")
        shares.append(_wall_share(tmp_path / f"{robots}.png"))
    assert shares[1] > 0.8 * shares[0] > 0.1


def test_a_region_partition_is_drawn_one_colour_per_region(tmp_path):
    """Pereira's robots share one region graph: the figure colours its places by region,
    so as many of the palette's colours show as there are regions (up to the palette's size)."""
    import matplotlib.pyplot as plt
    result = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=3, seed=1, strategy="pereira", max_sim_s=120,
                                       radio="eu868-g3"))
    regions = np.unique(result.agents[0].scheme.drawables()["regions"])
    plot_mission(result, tmp_path / "regions.png")
    rgb = np.asarray(Image.open(tmp_path / "regions.png").convert("RGB"), np.int16)
    right = rgb[:, rgb.shape[1] // 2:].reshape(-1, 3)
    palette = np.round(np.asarray(plt.get_cmap("tab20").colors) * 255).astype(np.int16)
    shown = sum(bool((np.abs(right - colour).max(axis=1) <= 2).any()) for colour in palette)
    assert len(regions) >= 2 and shown >= min(len(regions), len(palette))

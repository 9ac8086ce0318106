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

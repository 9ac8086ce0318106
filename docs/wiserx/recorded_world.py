"""The simulated world of the next mission, for measurement scripts that read the truth (true
poses, what each robot observed) from a mission observer, which is handed only the agents."""
import host_tools.mission as mission


def record_worlds() -> list:
    """From now on, every World a mission builds is appended to the returned list."""
    worlds = []

    class Recorded(mission.World):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            worlds.append(self)

    mission.World = Recorded
    return worlds

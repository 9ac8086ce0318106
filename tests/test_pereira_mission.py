"""Pereira et al.'s scheme end to end on the simulated HAL: a small team explores a cave by
itself over eu868-g3, and every robot ends holding the same records and so the same
region graph (pereira.md 6.3 bars 1, 2 and 8, on a small map)."""
import dataclasses

from firmware.comms.frame import decode_frame
from host_tools.mission import MissionConfig, run_mission


def test_a_team_finishes_a_cave_and_every_robot_holds_the_same_region_graph():
    r = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=3, seed=1, strategy="pereira", max_sim_s=900,
                                  radio="eu868-g3"))
    assert r.termination == "complete" and r.coverage >= 0.99 and r.robots_in_wall == 0
    stats = r.to_json()["explorer_stats"]
    assert all(n > 0 for n in stats["places_sent"]) and all(n > 0 for n in stats["intents_sent"])
    assert sum(stats["gates_sent"]) > 0 and sum(stats["claims_sent"]) > 0
    assert min(stats["regions"]) >= 2
    assert sum(stats["records_pushed"]) == 0        # in range with nothing lost, no teammate lags
    stores = [a.scheme.store for a in r.agents]
    assert len({s.digest() for s in stores}) == 1
    assert len({s.graph().digest() for s in stores}) == 1


def test_records_lost_once_on_their_way_to_a_robot_still_reach_it_before_the_mission_ends():
    """Every place, gate and claim robot 1 sends is lost once on its way to robot 0 (any
    sender's frame that first carries it); later copies get through. A record sent as its
    origin finishes is repaired too: the mission does not end while a teammate's summary
    shows it lacking, so every robot ends with the same records."""
    offered: set[tuple[str, int]] = set()

    def lose_first_copy(sender: int, receiver: int, payload: bytes) -> bool:
        frame = decode_frame(payload).frame
        if receiver != 0 or frame is None:
            return False
        firsts = {(name, v["oseq"]) for name, v in frame.records
                  if name in ("place", "gate", "claim") and v["sender_id"] == 1} - offered
        offered.update(firsts)
        return bool(firsts)

    r = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=3, seed=1, strategy="pereira", max_sim_s=900,
                                  radio="eu868-g3"), loss_rule=lose_first_copy)
    assert r.termination == "complete" and offered
    assert sum(r.to_json()["explorer_stats"]["records_pushed"]) > 0
    stores = [a.scheme.store for a in r.agents]
    assert len({s.digest() for s in stores}) == 1


def test_a_flush_phase_keeps_the_radios_going_after_the_end_without_changing_the_mission():
    """`--flush-s`: once every robot has stopped the radios go on for that long; T_total and
    the radio's figures are the mission's own, the flush's frames are counted apart, and the
    report compares what each robot holds."""
    cfg = MissionConfig(map_spec="cave:5:20x20", robots=3, seed=0, strategy="pereira", max_sim_s=600,
                        radio="eu868-g3")
    plain = run_mission(cfg).to_json()
    flushed = run_mission(dataclasses.replace(cfg, flush_s=60.0)).to_json()
    assert plain["termination"] == flushed["termination"] == "complete"
    assert flushed["t_total_s"] == plain["t_total_s"] < 600 - 60
    assert flushed["settled_s"] == plain["settled_s"] >= plain["t_total_s"]
    assert flushed["radio_stats"]["frames_sent"] == plain["radio_stats"]["frames_sent"]
    assert flushed["radio_stats"]["bytes_per_s_mean"] == plain["radio_stats"]["bytes_per_s_mean"]
    assert "flush" not in plain
    f = flushed["flush"]
    assert f["flush_s"] == 60.0 and f["ran_s"] == 60.0
    assert all(n > 0 for n in f["frames_sent"]) and all(b > 0 for b in f["bytes_sent"])   # summaries, heartbeats
    for report in (plain, flushed):
        digests = report["scheme_digests"]
        assert digests["agree"] and len(digests["per_robot"]) == 3
        assert set(digests["per_robot"][0]) == {"records", "region_graph"}


def test_the_report_says_when_robots_hold_different_shared_state():
    """Robot 2 hears nothing at all: its records and region graph differ from the others'."""
    r = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=3, seed=0, strategy="pereira", max_sim_s=600,
                                  radio="eu868-g3"), loss_rule=lambda sender, receiver, payload: receiver == 2)
    digests = r.to_json()["scheme_digests"]
    assert not digests["agree"]
    assert digests["per_robot"][0] == digests["per_robot"][1] != digests["per_robot"][2]


def test_schemes_without_shared_state_report_no_digests():
    r = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=2, seed=0, strategy="independent", max_sim_s=30))
    assert "scheme_digests" not in r.to_json()


def test_t_total_is_when_the_last_robot_stopped_not_when_its_news_had_gone():
    """The last summaries still on their way keep the mission (settled_s) going after every
    robot has stopped (t_total_s): the team explored no longer for that."""
    r = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=3, seed=1, strategy="pereira", max_sim_s=900,
                                  radio="eu868-g3"))
    report = r.to_json()
    assert report["termination"] == "complete"
    assert report["settled_s"] == r.sim_s > report["t_total_s"]
    quiet = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=2, seed=0, strategy="independent",
                                      max_sim_s=600)).to_json()
    assert quiet["settled_s"] == quiet["t_total_s"]
    cut = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=2, seed=0, strategy="independent",
                                    max_sim_s=5)).to_json()
    assert cut["settled_s"] is None and cut["t_total_s"] == 5.0

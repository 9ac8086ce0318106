"""Pushes (Pereira's gossip, gossip.py): a robot answers a teammate's summary with the records
it lacks, and takes back those another robot sends first, even once they wait on the link
for this robot's TDMA slot."""
from firmware.comms.frame import decode_frame
from firmware.comms.link import LinkLayer
from firmware.params import ExplorationParams, TaskRates
from firmware.schemes import all_dialects, build
from firmware.schemes.base import Services
from firmware.schemes.pereira.records import Place, Summary, values_of
from firmware.services.local_map import LocalMap
from firmware.services.roster import Roster
from firmware.services.topo_map import TopoMap
from firmware.services.waypoints import WaypointSet
from hal.lora import profile
from tests.doubles import FakeRadio

ME, ASKER, ORIGIN = 0, 1, 2
P = ExplorationParams()


def _robot():
    link = LinkLayer(ME, profile("eu868-g3"), dialect=build("pereira").dialect, dialects=all_dialects())
    scheme = build("pereira")
    scheme.attach(Services(ME, P, TaskRates(), LocalMap(P, 0.0, 0.0), WaypointSet(P),
                           TopoMap(P.d_build_m, P.d_connect_m), Roster(ME), send=link.enqueue, mesh=None,
                           last_scan_binned=None, has_planned=lambda: True, queued=link.queued,
                           withdraw=link.withdraw, on_air_until_us=link.on_air_until_us))
    outbox = next(t for t in scheme.tasks() if t.name == "pereira_outbox")
    return scheme, link, outbox


def _place(oseq: int) -> Place:
    return Place(ORIGIN, oseq, 10 * oseq, 0, 8, 1 if oseq > 1 else 0)


def _asked_for_three():
    """This robot holds three places of ORIGIN; ASKER's summaries say it holds none (the
    second one asks: a push answers only for records held when the previous one came)."""
    scheme, link, outbox = _robot()
    for q in (1, 2, 3):
        scheme.on_record("place", values_of(_place(q)), 0)
    for t_us in (1_000_000, 11_000_000):
        scheme.on_record("summary", values_of(Summary(ASKER, ((ORIGIN, 0),))), t_us)
    outbox.run(11_050_000)
    return scheme, link


def _sent_places(link: LinkLayer) -> list[int]:
    radio = FakeRadio(profile("eu868-g3"))
    link.service(0, radio)
    return [v["oseq"] for _name, v in decode_frame(radio.sent[0][1]).frame.records]


def test_a_summary_lacking_records_is_answered_with_them():
    scheme, link = _asked_for_three()
    assert link.queued("place") == 3 and scheme.stats()["records_pushed"] == 3
    assert _sent_places(link) == [1, 2, 3]


def test_a_push_waiting_on_the_link_is_taken_back_when_another_robot_sends_the_record():
    scheme, link = _asked_for_three()
    scheme.on_record("place", values_of(_place(2)), 11_100_000)      # another robot pushed it first
    assert link.queued("place") == 2 and scheme.stats()["pushes_withdrawn"] == 1
    assert _sent_places(link) == [1, 3]

"""Meier's repairs on a real link layer: a teammate's poly_nack names frames of this robot it
lost, and the polygon records they carried go again; a repair lost in turn is not sent again
on request (the block summaries find what it leaves), so repairs of repairs cannot pile up
where teammates go in and out of range."""
from firmware.comms.frame import decode_frame
from firmware.comms.link import LinkLayer
from firmware.params import ExplorationParams, TaskRates
from firmware.schemes import all_dialects, build
from firmware.schemes.base import Services
from firmware.schemes.meier.records import nack_values
from firmware.services.local_map import LocalMap
from firmware.services.roster import Roster
from firmware.services.topo_map import TopoMap
from firmware.services.waypoints import WaypointSet
from hal.lora import profile
from tests.doubles import FakeRadio, paint_box

ME, TEAMMATE = 0, 1
P = ExplorationParams()
S = 1_000_000


class _Robot:
    """A Meier scheme on a link layer, its own map a walled room 4 m x 3 m."""

    def __init__(self) -> None:
        self.link = LinkLayer(ME, profile("eu868-g3"), dialect=build("meier").dialect, dialects=all_dialects())
        self.radio = FakeRadio(profile("eu868-g3"))
        lm = LocalMap(P, 0.0, 0.0)
        paint_box(lm, -2.2, 2.2, -1.7, 1.7, 5.0)
        paint_box(lm, -2.0, 2.0, -1.5, 1.5, -5.0)
        self.scheme = build("meier")
        self.scheme.attach(Services(ME, P, TaskRates(), lm, WaypointSet(P), TopoMap(P.d_build_m, P.d_connect_m),
                                    Roster(ME), send=self.link.enqueue, mesh=None, last_scan_binned=None,
                                    has_planned=lambda: True, queued=self.link.queued,
                                    on_air_until_us=self.link.on_air_until_us, radio_Bps=None,
                                    bytes_sent=lambda: 0, keys_sent_in=self.link.keys_sent_in))
        self.tasks = {t.name: t for t in self.scheme.tasks()}

    def send_frame(self, now_us: int) -> list[str]:
        """The outbox feeds the link and the link sends one frame: its record types."""
        self.tasks["poly_outbox"].run(now_us)
        self.radio.now_us = now_us
        before = len(self.radio.sent)
        self.link.service(now_us, self.radio)
        assert len(self.radio.sent) == before + 1
        return [name for name, _ in decode_frame(self.radio.sent[-1][1]).frame.records]

    def nack(self, seq: int, now_us: int) -> int:
        """TEAMMATE names this robot's frame `seq` as lost: the records posted again."""
        before = self.scheme.stats()["poly_records_sent_again"]
        for values in nack_values(TEAMMATE, ME, [seq]):
            self.scheme.on_record("poly_nack", values, now_us)
        return self.scheme.stats()["poly_records_sent_again"] - before


def test_a_lost_frame_is_sent_again_but_a_lost_repair_is_left_to_the_summaries():
    robot = _Robot()
    robot.tasks["polygons"].run(1 * S)
    first = robot.send_frame(1 * S)
    assert first.count("poly") >= 3                      # the room's ring
    assert robot.nack(0, 2 * S) == first.count("poly")   # frame 0 lost: its records go again
    again = robot.send_frame(20 * S)
    assert again.count("poly") == first.count("poly")
    assert robot.nack(1, 21 * S) == 0                    # frame 1, the repair, lost: nothing
    assert robot.nack(0, 22 * S) == first.count("poly")  # frame 0 asked for again: it goes again

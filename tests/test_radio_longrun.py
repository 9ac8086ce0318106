"""Issue 3 acceptance on the real channel: in every profile, over more than an hour of
saturating traffic, no node exceeds its duty-cycle budget in any one-hour window, and the
inspector's per-sender statistics agree with the link layers' counters."""
import pytest

from firmware.comms.link import LinkLayer
from firmware.schemes.bayer_faigl.records import DIALECT as BF
from hal.lora import PROFILES
from hal.sim.radio import SimRadioModem
from host_tools.cmd_inspect import sender_stats
from radio_sim.channel import Channel
from tests.doubles import StepClock

TICK_US = 100_000
SIM_US = 2 * 3_600_000_000 + 600_000_000   # two hours and ten minutes


class _ListenOnly:
    def __init__(self, radio):
        self.radio = radio

    def transmit(self, payload):
        return False

    def busy(self):
        return self.radio.busy()

    def poll(self):
        return self.radio.poll()


@pytest.mark.parametrize("name", sorted(PROFILES))
def test_duty_cycle_and_inspector_agree_over_two_hours(name):
    prof = PROFILES[name]
    channel = Channel(prof, seed=4)
    clock = StepClock()
    air = []
    channel.add_sink(air.append)
    n = 3
    for i in range(n):
        channel.attach(i, lambda i=i: (3.0 * i, 0.0))
    radios = [SimRadioModem(channel, i, clock) for i in range(n)]
    links = [LinkLayer(i, prof, dialect=BF) for i in range(n)]   # robots running Bayer & Faigl
    k = 0
    while clock.t_us < SIM_US:
        for i, (link, radio) in enumerate(zip(links, radios)):
            while link.queue_len < 20:   # always more to say than the law allows
                k += 1
                link.enqueue("topo", dict(sender_id=i, x_cm=k % 100000, y_cm=i, z_cm=0, presence=1,
                                          e_inf_code=k % 256, info_version=k % 128))
            link.service(clock.t_us, radio)
        clock.t_us += TICK_US
        channel.advance_to(clock.t_us)
    # Let every link hear what already arrived, without starting another frame.
    for link, radio in zip(links, radios):
        link.service(clock.t_us, _ListenOnly(radio))
    stats = sender_stats(air, prof, duration_us=SIM_US)
    for link in links:
        c, st = link.counters, stats[link.node_id]
        assert st.frames == c["sent.frames"] > 0
        assert st.bytes == c["sent.bytes"]
        assert st.airtime_us_by_sub_band == {prof.sub_band: c[f"airtime_us.{prof.sub_band}"]}
        got = sum(stats[o].rx_by_receiver.get(link.node_id, {}).get("received", 0) for o in stats)
        assert got == c["received.ok"]
        if prof.duty_cycle is not None:
            worst = st.duty_cycle_max_by_sub_band[prof.sub_band]
            assert worst <= prof.duty_cycle
            assert worst > 0.9 * prof.duty_cycle          # saturated: the budget was really used
            assert c["deferred.duty_cycle"] > 0
        if prof.byte_rate_cap_Bps is not None:
            budget = prof.byte_rate_cap_Bps * SIM_US / 1e6
            assert 0.9 * budget < st.bytes <= budget + prof.max_payload_bytes

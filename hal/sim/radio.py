"""Simulated LoRa modem: the RadioModem HAL over the shared in-process channel.

It behaves like the RN2483 driver over a real or virtual modem, so both backends give the
firmware identical results:
- reception is one-shot (`radio rx 0` ends after one frame, and `radio tx` leaves receive
  mode); the RN2483 driver re-arms with `radio rx 0` each time it collects what arrived.
  `poll()` does the same: it drains the channel's events for this node, then re-arms the
  receiver unless the node is still transmitting. Frames that start while the receiver is
  disarmed (between a delivery or a transmission's end and the next poll) are missed, as
  they are on the real modem.
- an injected duplicate (radio_sim.faults) is handed over when the receiver is armed, so
  it uses up a one-shot reception like any frame and may show up one poll later.
- `busy()` asks the channel (the one source of truth for who is on the air).
"""
from __future__ import annotations

from typing import Callable, Sequence

from hal.config import BuildContext, ConfigError
from hal.interfaces import Clock
from hal.samples import RadioEvent
from hal.sim.realtime_world import RESOURCE
from radio_sim.channel import Channel


class SimRadioModem:
    # Built from configuration (hal.config): node robot_id on the channel of the
    # configuration's [world], on the robot's radio profile, stamped by the robot's clock.
    SETTINGS = ()
    RESOURCES = (RESOURCE,)

    def __init__(self, channel: Channel, node_id: int, clock: Clock) -> None:
        self.channel = channel
        self.node_id = int(node_id)
        self.clock = clock

    @classmethod
    def from_config(cls, ctx: BuildContext) -> SimRadioModem:
        if ctx.radio_profile is None or ctx.clock is None:
            raise ConfigError(None, "a simulated radio needs the robot's radio profile and clock")
        channel = ctx.resource(RESOURCE).channel(ctx.radio_profile, ctx.robot_id)
        return cls(channel, ctx.robot_id, ctx.clock)

    def transmit(self, payload: bytes) -> bool:
        return self.channel.transmit(self.node_id, payload, self.clock.now_us()) is not None

    def busy(self) -> bool:
        self.channel.advance_to(self.clock.now_us())
        return self.channel.transmitting(self.node_id)

    def poll(self) -> tuple[RadioEvent, ...]:
        now_us = self.clock.now_us()
        self.channel.advance_to(now_us)
        events = tuple(self.channel.take_events(self.node_id))
        if not self.channel.transmitting(self.node_id):
            self.channel.set_listening(self.node_id, True, now_us)
        return events


def attach_sim_radios(
    channel: Channel,
    clock: Clock,
    position_fns: Sequence[Callable[[], tuple[float, float]]],
    first_node_id: int = 0,
) -> list[SimRadioModem]:
    """Attach one node per position function (ids first_node_id, first_node_id + 1, ...) and
    return their modems in the same order."""
    modems = []
    for offset, position_fn in enumerate(position_fns):
        node_id = first_node_id + offset
        channel.attach(node_id, position_fn)
        modems.append(SimRadioModem(channel, node_id, clock))
    return modems

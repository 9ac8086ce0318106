"""An ideal in-process broadcast bus standing in for a WiFi mesh: no loss, no delay beyond
one tick, unlimited bandwidth. It counts every byte, because what the dense-map baselines
would need from a real link is the point of comparing with them."""
from __future__ import annotations


class SimMeshBus:
    def __init__(self) -> None:
        self._inboxes: dict[int, list[bytes]] = {}
        self.bytes_sent: dict[int, int] = {}
        self.messages_sent: dict[int, int] = {}

    def endpoint(self, robot_id: int) -> "SimMeshLink":
        self._inboxes[robot_id] = []
        self.bytes_sent[robot_id] = 0
        self.messages_sent[robot_id] = 0
        return SimMeshLink(self, robot_id)


class SimMeshLink:
    def __init__(self, bus: SimMeshBus, robot_id: int) -> None:
        self._bus = bus
        self._id = robot_id

    def broadcast(self, message: bytes) -> None:
        bus = self._bus
        bus.bytes_sent[self._id] += len(message)
        bus.messages_sent[self._id] += 1
        for rid, inbox in bus._inboxes.items():
            if rid != self._id:
                inbox.append(bytes(message))

    def receive(self) -> tuple[bytes, ...]:
        inbox = self._bus._inboxes[self._id]
        out = tuple(inbox)
        inbox.clear()
        return out

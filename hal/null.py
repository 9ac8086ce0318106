"""Null backends: the peripherals a robot is not fitted with. Each answers as an idle
device would (nothing measured, nothing heard, nothing sent), so a robot without one runs
the same code; `Hal.has` tells fitted from not, and a scheme that needs a peripheral the
robot lacks refuses to start (firmware.agent)."""
from __future__ import annotations

from hal.samples import AoaBearing, RadioEvent, UwbRange


class NullPeripheral:
    """Marks a null backend. Built from configuration like any backend (hal.config), with
    nothing to configure: `backend = "null"`, or no table at all for an optional peripheral."""

    SETTINGS = ()
    RESOURCES = ()

    @classmethod
    def from_config(cls, ctx) -> NullPeripheral:
        return cls()


class NullUwbRanger(NullPeripheral):
    def ranges(self) -> tuple[UwbRange, ...]:
        return ()


class NullWifiAoa(NullPeripheral):
    def bearings(self) -> tuple[AoaBearing, ...]:
        return ()


class NullRadioModem(NullPeripheral):
    def transmit(self, payload: bytes) -> bool:
        return False

    def busy(self) -> bool:
        return False

    def poll(self) -> tuple[RadioEvent, ...]:
        return ()


class NullMeshLink(NullPeripheral):
    def broadcast(self, message: bytes) -> None:
        pass

    def receive(self) -> tuple[bytes, ...]:
        return ()

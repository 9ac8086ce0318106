"""The dense-map baseline: another scheme's coordination, with every robot's scans shared
over an unconstrained mesh link as well (Bayer & Faigl's "full" comparison).

It composes the inner scheme, found by name in the registry (never imported), and adds one
thing: at every d_build of travel, the newest scan as a keyframe on the mesh; keyframes
heard are folded into the local map, so each robot plans on everything its team has seen.
"""
from __future__ import annotations

from collections.abc import Mapping

from firmware.scheduler import Task
from firmware.schemes.base import Candidate, PlanningView, Scheme, Services
from firmware.schemes.dense_baseline.keyframes import decode_keyframe, encode_keyframe
from firmware.services.pose import TravelMilestones
from firmware.services.targets import Target
from hal.samples import OdometrySample

# The inner scheme of each variant, as a registry spec.
INNER = {"greedy": "bayer-faigl:greedy", "minpos": "bayer-faigl:minpos", "meier": "meier:targets"}


class DenseBaseline(Scheme):
    name = "dense"
    doc = "a scheme's coordination plus dense keyframe scans over an ideal mesh link"
    variants = {"greedy": "Greedy with dense maps shared over an unconstrained link",
                "minpos": "MinPos with dense maps shared over an unconstrained link",
                "meier": "Meier et al.'s target broadcast and utility discount with dense maps shared over an "
                         "unconstrained link (the paper's comparison)"}
    default_variant = "minpos"
    needs = frozenset({"mesh"})

    def __init__(self, variant: str = "") -> None:
        super().__init__(variant)
        from firmware.schemes import build    # the registry; composing, not importing a scheme
        self.inner = build(INNER[self.variant])
        self.dialect = self.inner.dialect     # it sends the inner scheme's records, no others

    def needs_of(self) -> frozenset[str]:
        return self.needs | self.inner.needs_of()

    def attach(self, services: Services) -> None:
        super().attach(services)
        self.inner.attach(services)
        self._milestones = TravelMilestones(services.params.d_build_m)
        self.keyframes_sent = 0

    def tasks(self) -> list[Task]:
        return [Task("mesh", self.s.rates.radio_hz, self._task_mesh)] + self.inner.tasks()

    def _task_mesh(self, now_us: int) -> None:
        for message in self.s.mesh.receive():
            kf = decode_keyframe(message)
            if kf is not None:
                self.s.local_map.integrate_keyframe(kf[1])

    def on_record(self, rtype: str, values: Mapping[str, int], now_us: int) -> None:
        self.inner.on_record(rtype, values, now_us)

    def on_travel(self, pose: OdometrySample, now_us: int) -> None:
        if self._milestones.due(pose.x_m, pose.y_m) and self.s.has_planned():
            self.s.mesh.broadcast(encode_keyframe(self.s.robot_id, self.s.last_scan_binned()))
            self.keyframes_sent += 1
            self._milestones.mark(pose.x_m, pose.y_m)
        self.inner.on_travel(pose, now_us)

    def on_target_outcome(self, target: Target, outcome: str) -> None:
        self.inner.on_target_outcome(target, outcome)

    def filter_waypoints(self, view: PlanningView) -> None:
        self.inner.filter_waypoints(view)

    def rank(self, view: PlanningView, own: list[Candidate]) -> list[Candidate]:
        return self.inner.rank(view, own)

    def after_plan(self, pose: OdometrySample, now_us: int) -> None:
        self.inner.after_plan(pose, now_us)

    def stats(self) -> dict[str, int]:
        return {**self.inner.stats(), "keyframes_sent": self.keyframes_sent}

    def drawables(self) -> dict:
        return self.inner.drawables()

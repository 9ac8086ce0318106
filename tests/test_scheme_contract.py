"""One contract, every registered scheme (python-can's pattern): it starts on the simulated
HAL with what it declares it needs, sends only its own records and the core heartbeat,
survives any records of its own types, reports stable statistics, and a small team of it
finishes a tiny map by itself."""
import dataclasses
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from firmware.agent import ExplorerAgent
from firmware.comms.frame import decode_frame
from firmware.comms.schema import record_type
from firmware.schemes import SCHEMES, build, scheme_class, specs
from firmware.schemes.base import NEEDS, Scheme
from firmware.services.deployment import Deployment
from hal.lora import profile
from hal.sim.mesh import SimMeshBus
from host_tools.mission import MissionConfig, run_mission
from tests.doubles import ScriptedHal

CORE_RECORDS = {"pose"}    # the heartbeat every talking robot sends


@pytest.fixture(scope="module", params=specs())
def spec(request) -> str:
    return request.param


def test_every_scheme_declares_itself(spec):
    scheme = build(spec)
    assert isinstance(scheme, Scheme) and scheme.spec == spec
    assert scheme.name in SCHEMES and scheme.doc and scheme.variants[scheme.variant]
    assert scheme.needs_of() <= set(NEEDS), "needs are named from schemes.base.NEEDS"
    for name in scheme.records:
        assert record_type(name).size_bytes <= 255


def _robot(spec: str) -> tuple[ScriptedHal, ExplorerAgent]:
    fake = ScriptedHal(np.full(360, 3.0))
    hal = fake.hal()
    scheme = build(spec)
    if "mesh" in scheme.needs_of():
        hal = dataclasses.replace(hal, mesh=SimMeshBus().endpoint(0))
    if "region_map" in scheme.needs_of():
        scheme.load_region_map(())          # a building with no doorways
    plan = None
    if "floor_plan" in scheme.needs_of():    # a 20 m square, all of it navigable
        plan = Deployment((-10.0, -10.0, 10.0, 10.0), (0.0, 0.0, 0.0), 1, np.ones((20, 20)), 1.0)
    agent = ExplorerAgent(hal, scheme=scheme, radio_profile=profile("ideal-100Bps"), deployment=plan)
    agent.setup()
    return fake, agent


def _random_records(spec: str):
    scheme = build(spec)
    if not scheme.records:
        return st.just([])

    def one(name):
        rt = record_type(name)
        return st.fixed_dictionaries({f.name: st.integers(f.min_value, f.max_value) for f in rt.fields}) \
            .map(lambda v, name=name: (name, v))
    return st.lists(st.one_of([one(n) for n in scheme.records]), max_size=30)


@pytest.mark.parametrize("spec_", specs())
def test_a_scheme_survives_any_records_of_its_own_types(spec_):
    @settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(_random_records(spec_))
    def check(records):
        fake, agent = _robot(spec_)
        for name, values in records:
            agent.scheme.on_record(name, values, 0)
        fake.run(agent, 3)      # planning cycles on whatever those records said
        assert set(agent.stats()) >= {"targets_reached", "targets_unreachable", "bumps"}
    check()


def test_a_small_team_finishes_a_tiny_map_and_sends_only_its_own_records(spec):
    r = run_mission(MissionConfig(map_spec="cave:5:20x20", robots=2, seed=1, max_sim_s=1800, radio="eu868-g3",
                                  strategy=spec))
    assert r.termination == "complete" and r.coverage >= 0.99 and r.robots_in_wall == 0
    assert all(len(v) == 2 for v in r.to_json()["explorer_stats"].values())
    scheme = build(spec)
    sent = {name for air in r.air_frames for name, _ in decode_frame(air.payload).frame.records}
    if "radio" in scheme.needs_of():
        assert sent <= set(scheme.records) | CORE_RECORDS
        assert "pose" in sent, "a robot that talks sends its heartbeat"
    else:
        assert sent == set()


def test_the_registry_imports_only_the_scheme_asked_for():
    code = ("import sys; from firmware.schemes import build, SCHEMES; build('independent'); "
            "print(sorted(m for m, _ in SCHEMES.values() if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "['firmware.schemes.independent']"
    for name, (module, _cls) in SCHEMES.items():
        assert scheme_class(name).__module__.startswith(module)

"""Each scheme's dialect: found through the registry, in every node's dialect set, record
names unique across dialects; Bayer & Faigl's e_inf scale."""
import pytest

from firmware.comms.schema import CORE
from firmware.schemes import SCHEMES, all_dialects, build, catalogue, scheme_class
from firmware.schemes.bayer_faigl.records import DIALECT as BF, e_inf_bit_to_code, e_inf_code_to_bit
from firmware.services.topo_map import TOPO_FIELDS


def test_every_registered_schemes_dialect_is_in_all_dialects():
    ds = all_dialects()
    assert CORE in ds and ds.core is CORE
    for spec, _ in catalogue():
        scheme = build(spec)
        if scheme.dialect is not None:
            assert scheme.dialect in ds, spec
            assert scheme.records == tuple(r.name for r in scheme.dialect.records)
        else:
            assert scheme.records == ()
    from_classes = {scheme_class(n).dialect for n in SCHEMES} - {None}
    assert {d for d in ds} == from_classes | {CORE}


def test_what_each_scheme_sends():
    assert build("bayer-faigl:minpos").dialect is BF and build("bayer-faigl").records == ("topo",)
    assert build("dense:greedy").dialect is BF            # the inner scheme's records
    assert build("independent").dialect is None


def test_record_names_and_dialect_ids_are_unique_across_dialects():
    ds = all_dialects()
    names = [r.name for d in ds for r in d.records]
    assert len(names) == len(set(names)) == len(ds.record_names())
    assert len({d.id for d in ds}) == len(ds) and len({d.name for d in ds}) == len(ds)


def test_topo_record_is_a_row_of_the_topological_map():
    assert tuple(f.name for f in BF.by_name["topo"].fields) == TOPO_FIELDS


def test_e_inf_scale_is_monotone_and_saturating():
    codes = [e_inf_bit_to_code(e) for e in (0.0, 0.5, 1.0, 10.0, 100.0, 1e4, 1e5, 1e9)]
    assert codes == sorted(codes) and codes[0] == 0 and codes[-1] == 255
    assert e_inf_bit_to_code(float("nan")) == 0 and e_inf_bit_to_code(-3.0) == 0
    for code in range(256):
        assert e_inf_bit_to_code(e_inf_code_to_bit(code)) == code
    # 16 codes per octave: relative step about 4.4 %
    assert e_inf_code_to_bit(200) / e_inf_code_to_bit(199) == pytest.approx(2 ** (1 / 16), rel=1e-3)

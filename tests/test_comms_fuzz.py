"""Fuzz decode_frame with >= 100 000 random and mutated frames (10^6 with `pytest --slow`): it
never raises, and every rejection is counted under one of the fixed reasons, each of which
must show up."""
import time
from collections import Counter

import numpy as np
import pytest

from firmware.comms.codec import REASONS, Reason
from firmware.comms.frame import decode_frame, encode_frame_records, seal
from firmware.comms.frame import HEADER_BYTES, LENGTH_BYTE, OVERHEAD_BYTES
from firmware.comms.schema import FRAME_VERSION
from firmware.schemes import all_dialects
from world_sim.seeding import stream

# Every record of every dialect; a frame takes core records and one dialect's.
DIALECTS = tuple(all_dialects())
CORE_TYPES = DIALECTS[0].records

N_PER_CLASS = 12_800          # 8 classes -> 102 400 frames
N_PER_CLASS_SLOW = 125_000    # 8 classes -> 1 000 000 frames


def _valid_frames(rng: np.random.Generator, n: int) -> list[bytes]:
    """Valid frames with in-range values: bytes packed from random field values."""
    out = []
    for i in range(n):
        recs = []
        types = CORE_TYPES + DIALECTS[int(rng.integers(len(DIALECTS)))].records
        for _ in range(int(rng.integers(1, 8))):
            rt = types[int(rng.integers(len(types)))]
            word = 0
            for f in rt.fields:
                v = int(rng.integers(f.min_value, f.max_value + 1))
                word = (word << f.bits) | (v & ((1 << f.bits) - 1))
            recs.append((rt.name, (word << rt.padding_bits).to_bytes(rt.size_bytes, "big")))
        out.append(encode_frame_records(int(rng.integers(256)), int(rng.integers(65536)), recs,
                                        hops_left=int(rng.integers(16))))
    return out


def _split(buf: np.ndarray, lengths: np.ndarray) -> list[bytes]:
    blob = buf.tobytes()
    ends = np.cumsum(lengths)
    starts = ends - lengths
    return [blob[s:e] for s, e in zip(starts.tolist(), ends.tolist())]


def build_corpus(seed: int = 1, n: int = N_PER_CLASS) -> dict[str, list[bytes]]:
    rng = stream(seed, "test.comms.fuzz")
    base = _valid_frames(rng, 512)
    pick = rng.integers(len(base), size=(6, n))
    corpus: dict[str, list[bytes]] = {}

    lengths = rng.integers(0, 264, size=n)
    corpus["random"] = _split(rng.integers(0, 256, size=int(lengths.sum()), dtype=np.uint8), lengths)

    lengths = rng.integers(2, 264, size=n)
    raw = rng.integers(0, 256, size=int(lengths.sum()), dtype=np.uint8)
    starts = np.cumsum(lengths) - lengths
    raw[starts] = (raw[starts] & 0x0F) | (FRAME_VERSION << 4)       # our version nibble
    raw[starts + LENGTH_BYTE] = np.maximum(lengths - OVERHEAD_BYTES, 0).clip(0, 255)   # a self-consistent length byte
    # (the dialect byte stays random: mostly unknown dialects)
    corpus["random_versioned"] = _split(raw, lengths)

    flips = []
    n_bits = rng.integers(1, 3, size=n)                   # 1 or 2 flipped bits
    for k, (i, nb) in enumerate(zip(pick[0].tolist(), n_bits.tolist())):
        b = bytearray(base[i])
        for pos in rng.choice(len(b) * 8, size=nb, replace=False).tolist():
            b[pos // 8] ^= 0x80 >> (pos % 8)
        flips.append(bytes(b))
    corpus["bit_flips"] = flips

    cut = rng.random(n)
    corpus["truncated"] = [base[i][: int(len(base[i]) * c)] for i, c in zip(pick[1].tolist(), cut.tolist())]

    extra = rng.integers(1, 9, size=n)
    tails = _split(rng.integers(0, 256, size=int(extra.sum()), dtype=np.uint8), extra)
    corpus["extended"] = [base[i] + t for i, t in zip(pick[2].tolist(), tails)]

    # CRC-valid but semantically damaged: random payload bytes, resealed.
    resealed = []
    n_bytes = rng.integers(1, 4, size=n)
    for i, nb in zip(pick[3].tolist(), n_bytes.tolist()):
        b = bytearray(base[i][:-2])
        for pos in rng.integers(HEADER_BYTES, len(b), size=nb).tolist():
            b[pos] = int(rng.integers(256))
        resealed.append(seal(bytes(b)))
    corpus["resealed_payload"] = resealed

    # CRC-valid with a damaged frame type or length byte.
    hdr = []
    for k, i in enumerate(pick[4].tolist()):
        b = bytearray(base[i][:-2])
        if k % 2:
            b[0] = (FRAME_VERSION << 4) | int(rng.integers(16))
        else:
            b = b[:HEADER_BYTES] + b[HEADER_BYTES:][: int(rng.integers(0, len(b) - HEADER_BYTES))]
            b[LENGTH_BYTE] = len(b) - HEADER_BYTES
        hdr.append(seal(bytes(b)))
    corpus["resealed_header"] = hdr

    corpus["valid"] = [base[i] for i in pick[5].tolist()]
    return corpus


def test_fuzz_decode_frame_counts_every_rejection():
    _fuzz(N_PER_CLASS, 100_000)


@pytest.mark.slow
def test_fuzz_decode_frame_with_a_million_frames():
    _fuzz(N_PER_CLASS_SLOW, 1_000_000)


def _fuzz(n_per_class: int, at_least: int) -> None:
    corpus = build_corpus(n=n_per_class)
    total = sum(len(v) for v in corpus.values())
    assert total >= at_least
    per_class: dict[str, Counter] = {}
    t0 = time.perf_counter()
    for name, frames in corpus.items():
        c = Counter()
        for data in frames:
            res = decode_frame(data)          # an exception here fails the test
            c[res.reason] += 1
        per_class[name] = c
    elapsed_s = time.perf_counter() - t0
    hist = sum(per_class.values(), Counter())
    assert sum(hist.values()) == total
    assert set(hist) <= set(REASONS)
    missing = set(REASONS) - set(hist)
    assert not missing, f"reasons never produced: {missing}"
    assert per_class["valid"] == Counter({Reason.OK: n_per_class})
    assert Reason.OK not in per_class["bit_flips"]        # 0x8005 catches every 1- and 2-bit error
    assert Reason.OK not in per_class["extended"] and Reason.OK not in per_class["truncated"]
    assert set(per_class["extended"]) == {Reason.BAD_LENGTH}
    print(f"\nfuzz: {total} frames in {elapsed_s:.2f} s = {total / elapsed_s:,.0f} frames/s")
    print("reasons: " + ", ".join(f"{r.value}={hist[r]}" for r in REASONS))
    for name, c in per_class.items():
        print(f"  {name:18s} " + ", ".join(f"{r.value}={n}" for r, n in sorted(c.items())))

"""`make bench`'s JAUS fuzz corpus builds a valid datagram of every message type the codec knows
(a message added without a generator there broke `make bench` unnoticed: issue 19's
Report Identification)."""

from __future__ import annotations

import importlib.util
import random
from pathlib import Path

from overdrive.jaus import decode_datagram, encode_datagram, message_types

BENCH = Path(__file__).resolve().parents[2] / "bench" / "bench_jaus.py"


def _bench_jaus():
    spec = importlib.util.spec_from_file_location("bench_jaus", BENCH)
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_fuzz_corpus_has_every_message_type_and_each_round_trips() -> None:
    bench = _bench_jaus()
    rng = random.Random(7)
    for cls in message_types():
        message = bench.random_message(cls, rng)
        assert type(message) is cls
        decoded = decode_datagram(encode_datagram(message))   # scaled fields round to the wire
        assert [type(m) for m in decoded] == [cls], (cls, decoded)

"""JAUS codec benchmark and fuzz run.

Throughput: encode+decode round trips per second for Set Wrench Effort (the XGV's throttle /
steering / brake command) and Report Velocity State (all nine fields), next to a baseline
that only ``struct.pack``s and ``unpack``s the same header and payload integers, in the same
run. Target: >= 200,000 round trips per second on one core. Rates are per second of CPU time
(best of five runs), so a busy machine does not distort them.

Fuzz: mutated JUDP datagrams built from every message type (bit flips, overwrites,
insertions, deletions, truncations, extensions), each fed to ``decode_datagram`` and, minus
its framing, to ``decode``. Anything other than ``JausDecodeError`` is counted as unexpected
(must be 0).

    .venv/bin/python bench/bench_jaus.py [--pairs N] [--fuzz N] [--seed S]

Prints a table, then the results as one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import struct
import sys
import time
from collections import Counter
from typing import Any

from overdrive.fuzzing import mutate
from overdrive.jaus import (
    Header,
    Horn,
    JausDecodeError,
    JausId,
    JausTimestamp,
    Lights,
    Message,
    Motion,
    ReportComponentControl,
    ReportConfiguration,
    ReportErrorCount,
    ReportIdentification,
    ReportServices,
    ReportVelocityState,
    SetMotionProfile,
    SetWrenchEffort,
    UnknownMessage,
    decode,
    decode_datagram,
    encode,
    encode_datagram,
    message_types,
)
from overdrive.jaus.layout import PresenceLayout, ScaledWire
from overdrive.jaus.messages import MILLIS_U16, TIMESTAMP, ConfigurationNode, Service

TARGET_PAIRS_PER_S = 200_000
INT_BOUNDS = {"B": (0, 0xFF), "H": (0, 0xFFFF), "I": (0, 0xFFFFFFFF), "i": (-(2**31), 2**31 - 1)}

# --------------------------------------------------------------------------- throughput

WRENCH = SetWrenchEffort.xgv(throttle_pct=35.0, steering_pct=-12.5, brake_pct=0.0)
VELOCITY = ReportVelocityState(
    velocity_x_mps=8.25,
    velocity_y_mps=-0.125,
    velocity_z_mps=0.01,
    velocity_rms_mps=0.2,
    roll_rate_radps=0.001,
    pitch_rate_radps=-0.002,
    yaw_rate_radps=0.15,
    rate_rms_radps=0.01,
    timestamp=JausTimestamp(21, 13, 45, 30, 250),
)

# the baseline packs and unpacks the integers the codec puts on the wire (header + payload)
_LAYOUTS = {
    "set-wrench-effort": struct.Struct("<BBHIIHH" + "Hhhb"),
    "report-velocity-state": struct.Struct("<BBHIIHH" + "H3iI3hHI"),
}


def _baseline(name: str, message: Message) -> Any:
    layout = _LAYOUTS[name]
    raws = layout.unpack(encode(message))
    pack, unpack = layout.pack, layout.unpack
    return lambda: unpack(pack(*raws))


def _rate(function: Any, pairs: int, runs: int = 5) -> float:
    """Calls per second of CPU time, best of ``runs``: CPU time rather than wall time so
    other processes on the machine do not count against the codec ("on one core")."""
    best = math.inf
    for _ in range(runs):
        start = time.process_time()
        for _ in range(pairs):
            function()
        best = min(best, time.process_time() - start)
    return pairs / best


def throughput(pairs: int) -> dict[str, dict[str, float]]:
    results = {}
    for name, message in (("set-wrench-effort", WRENCH), ("report-velocity-state", VELOCITY)):
        baseline = _baseline(name, message)
        wire = encode(message)
        again = decode(wire)   # negative raws re-encode one step toward zero (docs/jaus.md)
        assert type(again) is type(message) and encode(again)[:16] == wire[:16]
        results[name] = {
            "codec_pairs_per_s": _rate(lambda m=message: decode(encode(m)), pairs),
            "encode_per_s": _rate(lambda m=message: encode(m), pairs),
            "decode_per_s": _rate(lambda w=wire: decode(w), pairs),
            "struct_baseline_pairs_per_s": _rate(baseline, pairs),
        }
    return results


# --------------------------------------------------------------------------- fuzz corpus


def _random_value(wire: Any, rng: random.Random) -> Any:
    if isinstance(wire, ScaledWire):
        lo, hi = wire.scaled.lo, wire.scaled.hi
        return rng.uniform(lo - (hi - lo) * 0.1, hi + (hi - lo) * 0.1)
    if wire is TIMESTAMP:
        return JausTimestamp(*(rng.randrange(limit) for limit in (32, 24, 60, 60, 1000)))
    if wire is MILLIS_U16:
        return rng.uniform(0.0, 65.535)
    if wire.to_raw is not None:  # curvature carried as atan
        return rng.uniform(-5.0, 5.0)
    return rng.randint(*INT_BOUNDS[wire.fmt])


def _random_header(rng: random.Random) -> Header:
    return Header(
        destination=JausId(*(rng.randint(1, 255) for _ in range(4))),
        source=JausId(*(rng.randint(1, 255) for _ in range(4))),
        priority=rng.randrange(16),
        ack_nak=rng.randrange(4),
        service_connection=rng.random() < 0.5,
        sequence=rng.randrange(0x10000),
    )


def random_message(cls: type[Message], rng: random.Random) -> Message:
    header = _random_header(rng)
    u8 = lambda: rng.randrange(256)  # noqa: E731
    if cls is SetMotionProfile:
        motions = tuple(
            Motion(rng.uniform(-10, 10), rng.uniform(0, 5), rng.uniform(-0.2, 0.2),
                   rng.uniform(0, 10), rng.uniform(0, 2))
            for _ in range(rng.randint(1, 3))
        )  # fmt: skip
        return SetMotionProfile(motions, header=header)
    if cls.name in ("set-signals", "report-signals"):
        return cls(  # type: ignore[call-arg]
            turn_signal=rng.choice([None, rng.randrange(4)]),
            horn=rng.choice([None, Horn(u8(), u8(), u8())]),
            lights=rng.choice([None, Lights(u8(), u8(), u8())]),
            header=header,
        )
    if cls is ReportErrorCount:
        counts = tuple(rng.randint(-(2**31), 2**31 - 1) for _ in range(rng.randint(0, 8)))
        return ReportErrorCount(counts=counts, header=header)
    if cls is ReportComponentControl:
        return ReportComponentControl(JausId(u8(), u8(), u8(), u8()), u8(), header)
    if cls is ReportIdentification:
        text = "".join(chr(rng.randrange(32, 127)) for _ in range(rng.randint(0, 40)))
        return ReportIdentification(u8(), u8(), rng.randrange(0x10000), text, header)
    if cls is ReportConfiguration:
        nodes = tuple(ConfigurationNode(u8(), tuple((u8(), u8()) for _ in range(rng.randint(0, 4))))
                      for _ in range(rng.randint(0, 3)))
        return ReportConfiguration(nodes, header)
    if cls is ReportServices:
        pairs = lambda: tuple((rng.randrange(0x10000), rng.randrange(2**32))  # noqa: E731
                              for _ in range(rng.randint(0, 3)))
        services = tuple(Service(rng.randrange(0x10000), pairs(), pairs())
                         for _ in range(rng.randint(0, 3)))
        return ReportServices(services, header)
    layout = cls.layout  # type: ignore[attr-defined]
    optional = isinstance(layout, PresenceLayout)
    values = {
        name: None if optional and rng.random() < 0.4 else _random_value(wire, rng)
        for name, wire in layout.fields
    }
    return cls(**values, header=header)


def corpus(rng: random.Random, size: int = 400) -> list[bytes]:
    """Valid datagrams: each message type alone, plus mixes of up to five."""
    types = [*message_types()]
    messages = [random_message(cls, rng) for cls in types for _ in range(3)]
    messages.append(UnknownMessage(0x9ABC, bytes(rng.randrange(256) for _ in range(12))))
    datagrams = [encode_datagram(m) for m in messages]
    while len(datagrams) < size:
        datagrams.append(encode_datagram(rng.sample(messages, rng.randint(2, 5))))
    return datagrams


def fuzz(count: int, seed: int) -> dict[str, Any]:
    rng = random.Random(seed)
    datagrams = corpus(rng)
    outcomes: Counter[str] = Counter()
    unexpected: list[str] = []
    start = time.perf_counter()
    for i in range(count):
        mutated = mutate(datagrams[i % len(datagrams)], rng)
        for decoder, data in ((decode_datagram, mutated), (decode, mutated[5:])):
            try:
                decoder(data)
                outcomes["decoded"] += 1
            except JausDecodeError:
                outcomes["rejected"] += 1
            except Exception as exc:  # the point of the fuzz: count anything else
                outcomes["unexpected"] += 1
                if len(unexpected) < 10:
                    unexpected.append(f"{type(exc).__name__}: {exc} on {mutated.hex()}")
    elapsed = time.perf_counter() - start
    return {
        "datagrams": count,
        "decode_calls": sum(outcomes.values()),
        "decoded": outcomes["decoded"],
        "rejected_with_jaus_decode_error": outcomes["rejected"],
        "unexpected_exceptions": outcomes["unexpected"],
        "unexpected_examples": unexpected,
        "seconds": elapsed,
    }


# --------------------------------------------------------------------------- report


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=50_000, help="calls per timing run")
    parser.add_argument("--fuzz", type=int, default=100_000, help="mutated datagrams")
    parser.add_argument("--seed", type=int, default=3794)
    args = parser.parse_args(argv)

    rates = throughput(args.pairs)
    fuzzed = fuzz(args.fuzz, args.seed)

    print(f"{'message':24} {'codec rt/s':>12} {'encode/s':>12} {'decode/s':>12} "
          f"{'struct rt/s':>12} {'struct/codec':>12}")  # fmt: skip
    for name, r in rates.items():
        ratio = r["struct_baseline_pairs_per_s"] / r["codec_pairs_per_s"]
        print(f"{name:24} {r['codec_pairs_per_s']:12,.0f} {r['encode_per_s']:12,.0f} "
              f"{r['decode_per_s']:12,.0f} {r['struct_baseline_pairs_per_s']:12,.0f} "
              f"{ratio:11.1f}x")  # fmt: skip
    print(f"target: {TARGET_PAIRS_PER_S:,} round trips/s (encode + decode)")
    print(f"fuzz: {fuzzed['datagrams']:,} mutated datagrams, {fuzzed['decode_calls']:,} decode "
          f"calls in {fuzzed['seconds']:.1f} s: {fuzzed['decoded']:,} decoded, "
          f"{fuzzed['rejected_with_jaus_decode_error']:,} rejected (JausDecodeError), "
          f"{fuzzed['unexpected_exceptions']} unexpected exceptions")  # fmt: skip
    for example in fuzzed["unexpected_examples"]:
        print("  unexpected:", example)

    result = {
        "throughput": rates,
        "target_pairs_per_s": TARGET_PAIRS_PER_S,
        "meets_target": all(r["codec_pairs_per_s"] >= TARGET_PAIRS_PER_S for r in rates.values()),
        "fuzz": fuzzed,
    }
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    outcome = main()
    sys.exit(0 if outcome["fuzz"]["unexpected_exceptions"] == 0 else 1)

"""Long-running fuzzing of overdrive's decoders and validators (outside CI).

Targets: ``jaus`` (JUDP datagrams and JAUS messages), ``scenario`` (scenario YAML text),
``wire`` (Zenoh bus frames), ``pacmod3`` (PACMod 3 CAN frames, both dialects: two bytes of id
and flags, then the data). Each may only accept input or raise its documented error; a PACMod 3
frame that decodes must also encode back to a frame that decodes to the same message.

    .venv/bin/python fuzz/run.py jaus --seconds 600          # hypothesis, any machine
    .venv/bin/python fuzz/run.py scenario --atheris -- -max_total_time=600   # coverage-guided

With ``--atheris`` (``pip install atheris``) the target runs under libFuzzer; otherwise a
seeded mutator of valid inputs (shipped scenarios, encoded messages) runs until the time is
up. An unexpected exception prints the input (hex) and its traceback, and exits 1.
"""

from __future__ import annotations

import argparse
import contextlib
import random
import sys
import time
from collections.abc import Callable

from overdrive.fuzzing import mutate


def jaus_target(data: bytes) -> None:
    from overdrive.jaus import JausError, decode, decode_datagram

    for fn in (decode, decode_datagram):
        with contextlib.suppress(JausError):
            fn(data)


def scenario_target(data: bytes) -> None:
    """What ``load_scenario`` does with a file's bytes, without the file."""
    from overdrive.scenario.safe_yaml import InputError, decode_utf8
    from overdrive.scenario.schema import ScenarioError, load_scenario_text

    with contextlib.suppress(InputError, ScenarioError):
        load_scenario_text(decode_utf8(data), "fuzz.yaml")


def wire_target(data: bytes) -> None:
    from overdrive.bus.wire import Registry, WireError

    global REGISTRY
    if REGISTRY is None:
        REGISTRY = Registry()
    with contextlib.suppress(WireError):
        REGISTRY.decode(data)


REGISTRY = None
CODECS: list = []


def pacmod3_frame(data: bytes):
    """Bytes as a CAN frame: bytes 0-1 the 11-bit id (bit 15: extended), the rest the data."""
    from overdrive.kits.frames import CanFrame

    head = int.from_bytes(data[:2].ljust(2, b"\0"), "big")
    return CanFrame(arbitration_id=head & 0x7FF, data=data[2:], is_extended=bool(head & 0x8000))


def pacmod3_target(data: bytes) -> None:
    from overdrive.kits.frames import KitError
    from overdrive.kits.pacmod3 import Pacmod3Codec

    if not CODECS:
        CODECS.extend([Pacmod3Codec("v3"), Pacmod3Codec("v14")])
    try:
        frame = pacmod3_frame(data)
    except KitError:
        return
    for codec in CODECS:
        try:
            msg = codec.decode(frame)
        except KitError:
            continue
        if codec.decode(codec.encode(msg)) != msg:
            raise AssertionError(f"{frame}: {msg} does not survive encode + decode")

TARGETS: dict[str, Callable[[bytes], None]] = {
    "jaus": jaus_target, "scenario": scenario_target, "wire": wire_target,
    "pacmod3": pacmod3_target}


def corpus(name: str) -> list[bytes]:
    """Valid inputs to mutate: shipped scenarios, encoded JAUS messages, bus frames."""
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    if name == "scenario":
        return [p.read_bytes() for p in sorted((root / "scenarios").rglob("*.yaml"))]
    if name == "pacmod3":
        return pacmod3_corpus()
    if name == "jaus":
        from overdrive.jaus import (
            ReportHeartbeatPulse,
            RequestComponentControl,
            SetMotionProfile,
            SetWrenchEffort,
            encode,
            encode_datagram,
        )

        msgs = [RequestComponentControl(), SetWrenchEffort.xgv(throttle_pct=30, steering_pct=-5,
                                                               brake_pct=0),
                SetMotionProfile.single(5.0, 2.0), ReportHeartbeatPulse()]
        return [encode(m) for m in msgs] + [encode_datagram(msgs)]
    from overdrive.bus.wire import Registry
    from overdrive.messages import MoveCommand, SetSpeed

    registry = Registry()
    return [registry.encode(MoveCommand(kind="move", distance_m=5, maxspeed_mps=2), "cli"),
            registry.encode(SetSpeed(speed_mps=1, accel_mps2=1, gear="drive", state="run"), "x")]


def pacmod3_corpus() -> list[bytes]:
    """One frame of every message both dialects use, as ``pacmod3_target`` reads bytes."""
    from overdrive.kits.pacmod3 import (
        AccelCmd,
        GlobalCmd,
        Pacmod3Codec,
        ShiftCmd,
        SteeringCmd,
        SteeringRpt,
        SupervisoryCtrl,
        VehicleSpeedRpt,
    )

    out = []
    for dialect, msgs in (("v3", [AccelCmd(enable=True, accel_ratio=0.5),
                                  SteeringCmd(enable=True, position_rad=-1.0,
                                              rotation_rate_radps=2.0),
                                  ShiftCmd(enable=True, gear=3),
                                  SteeringRpt(enabled=True, override_active=False,
                                              manual_input=0.1, commanded_value=0.2,
                                              output_value=0.3),
                                  VehicleSpeedRpt(speed_mps=3.0, valid=True)]),
                          ("v14", [GlobalCmd(counter=5), SupervisoryCtrl(counter=9, enable=True),
                                   AccelCmd(enable=True, accel_ratio=0.25),
                                   VehicleSpeedRpt(speed_mps=-1.0, valid=True)])):
        codec = Pacmod3Codec(dialect)  # type: ignore[arg-type]
        for msg in msgs:
            frame = codec.encode(msg)
            out.append(frame.arbitration_id.to_bytes(2, "big") + frame.data)
    return out


def run_random(name: str, target: Callable[[bytes], None], seconds: float, seed: int) -> int:
    """Mutate valid inputs (and try random bytes) until the time is up."""
    rng = random.Random(seed)
    seeds = corpus(name)
    deadline = time.monotonic() + seconds
    count = 0
    while time.monotonic() < deadline:
        data = rng.randbytes(rng.randint(0, 64)) if rng.random() < 0.1 else mutate(rng.choice(seeds), rng)
        try:
            target(data)
        except Exception:
            print(f"unexpected exception on input {data.hex()}", file=sys.stderr)
            raise
        count += 1
    print(f"{name}: {count} inputs in {seconds:.0f} s, no unexpected exception")
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("target", choices=sorted(TARGETS))
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--atheris", action="store_true", help="coverage-guided, via libFuzzer")
    args, rest = parser.parse_known_args()
    target = TARGETS[args.target]
    if args.atheris:
        import atheris

        with atheris.instrument_imports():
            import overdrive.bus.wire
            import overdrive.jaus
            import overdrive.kits.pacmod3
            import overdrive.scenario.schema  # noqa: F401
        atheris.Setup([sys.argv[0], *rest], target)
        atheris.Fuzz()
        return 0
    return run_random(args.target, target, args.seconds, args.seed)


if __name__ == "__main__":
    sys.exit(main())

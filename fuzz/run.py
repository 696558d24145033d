"""Long-running fuzzing of overdrive's decoders and validators (outside CI).

Targets: ``jaus`` (JUDP datagrams and JAUS messages), ``scenario`` (scenario YAML text),
``wire`` (Zenoh bus frames). Each may only accept input or raise its documented error.

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

TARGETS: dict[str, Callable[[bytes], None]] = {
    "jaus": jaus_target, "scenario": scenario_target, "wire": wire_target}


def corpus(name: str) -> list[bytes]:
    """Valid inputs to mutate: shipped scenarios, encoded JAUS messages, bus frames."""
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    if name == "scenario":
        return [p.read_bytes() for p in sorted((root / "scenarios").rglob("*.yaml"))]
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
            import overdrive.scenario.schema  # noqa: F401
        atheris.Setup([sys.argv[0], *rest], target)
        atheris.Fuzz()
        return 0
    return run_random(args.target, target, args.seconds, args.seed)


if __name__ == "__main__":
    sys.exit(main())

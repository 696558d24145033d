"""How the PACMod 3 client stops after a fault it detects, against the emulated kit in lock step
(docs/pacmod3-stack.md, "Engaging"): for each speed and fault, when the kit's own truth stands
and when the client lets the kit go, against the stop's time bound.

    .venv/bin/python scripts/pacmod3_stop_figures.py
"""

from __future__ import annotations

from overdrive.messages import PedalCommand, PowertrainCommand, SteerCommand, Topic
from overdrive.scenario.vehicles import KIT_VEHICLES
from overdrive.vehicle.pacmod3_client import Pacmod3Client
from overdrive.vehicle.pacmod3_engage import stop_bound_s
from overdrive.vehicle.pacmod3_kit import KitFault, Pacmod3Kit

STEP_S = 0.01
HOLD = PedalCommand(throttle_pct=0.0, brake_pct=60.0, source="speed")
GO = PedalCommand(throttle_pct=40.0, brake_pct=0.0, source="speed")


def run(kit, client, now_s, seconds, pedals, engage=False, hook=None, until=None):
    truths = []
    for _ in range(round(seconds / STEP_S)):
        now_s = round(now_s + STEP_S, 9)
        kit.step(now_s)
        for frame in kit.report_frames(now_s):
            client.receive(frame, now_s)
        client.sensor_outputs(now_s)
        client.take_inputs([(Topic.PEDALS, pedals),
                            (Topic.STEER, SteerCommand(steer_pct=0.0, source="driving")),
                            (Topic.POWERTRAIN, PowertrainCommand(gear="drive", engine_on=True,
                                                                 source="speed"))], now_s)
        if engage:
            engage = False
            client.request_engage(now_s)
        if hook is not None:
            hook(now_s)
        for frame in client.command_frames(now_s):
            kit.receive(frame, now_s)
        truths.append(kit.truth(now_s))
        if until is not None and until(truths[-1]):
            break
    return now_s, truths


def one(speed_mps: float, fault: str) -> str:
    params = KIT_VEHICLES["lexus-rx450h"]
    kit, client = Pacmod3Kit(params), Pacmod3Client(params)
    now, _ = run(kit, client, 0.0, 1.0, HOLD, engage=True)
    now, _ = run(kit, client, now, 1.5, HOLD)
    now, _ = run(kit, client, now, 20.0, GO, until=lambda t: t.speed_mps >= speed_mps)
    v = kit.truth(now).speed_mps
    x0 = kit.truth(now).odometer_m
    hook = None
    if fault == "bus error once":
        fired = []

        def hook(t: float) -> None:
            if not fired:
                fired.append(t)
                client.bus_error("no acknowledgement")
    else:
        kit.inject(KitFault(kind="silence", start_s=now,
                            end_s=now + 0.2 if fault == "silent 0.2 s" else None))
    start = now
    _, truths = run(kit, client, now, 8.0, GO, hook=hook)
    stood = next(t for t in truths if abs(t.speed_mps) < 1e-3)
    let_go = next(t for t in truths if "brake" not in t.enabled)
    return (f"| {v:.2f} | {fault} | {stood.t_s - start:.2f} | {stood.odometer_m - x0:.2f} | "
            f"{let_go.t_s - start:.2f} | {let_go.speed_mps:.3f} | {stop_bound_s(v):.2f} |")


def main() -> None:
    print("| speed (m/s) | fault | stood after (s) | distance (m) | let go after (s) | "
          "speed let go (m/s) | bound (s) |")
    print("|---|---|---|---|---|---|---|")
    for speed in (1.0, 4.19, 8.0):
        for fault in ("silent 0.2 s", "silent for good", "bus error once"):
            print(one(speed, fault))


if __name__ == "__main__":
    main()

"""The acceptance of issue 32 across processes: the emulated kit in one process, ``overdrive
drive --can pacmod3`` in another, over a socketcand hub on loopback (python-can's socketcand
interface), judged from the frames the kit took and the kit's own truth (its odometry)."""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader

from overdrive.runtime.can_hub import CanHub

pytestmark = pytest.mark.wallclock
ROOT = Path(__file__).resolve().parents[2]
OVERDRIVE = str(Path(sys.executable).parent / "overdrive")
SYSTEM_CMDS = ("AccelCmd", "BrakeCmd", "SteeringCmd", "ShiftCmd")


class Rig:
    def __init__(self, tmp_path: Path, kit_args: tuple[str, ...] = ()) -> None:
        self.tmp = tmp_path
        self.hub = CanHub(port=0).start()
        self.log = tmp_path / "kit.jsonl"
        self.kit = subprocess.Popen([sys.executable, "-m", "tests.can.kit_process",
                                     str(self.hub.port), str(self.log), *kit_args], cwd=ROOT)
        deadline = time.monotonic() + 20.0
        while not (self.log.exists() and self.log.read_text()):
            assert time.monotonic() < deadline and self.kit.poll() is None, "kit not started"
            time.sleep(0.05)
        self.start = json.loads(self.log.read_text().splitlines()[0])["start"]
        self.drive: subprocess.Popen | None = None
        self.out = tmp_path / "run"

    def run_drive(self, move: dict, duration_s: float, engage: bool = True,
                  extra: tuple[dict, ...] = ()) -> None:
        path = self.tmp / "scenario.yaml"
        path.write_text(yaml.safe_dump({"name": "across", "start": "ready", "seed": 1,
                                        "duration_s": duration_s,
                                        "events": [{"at_s": 1.5, "move": move}, *extra]}))
        self.drive = subprocess.Popen(
            [OVERDRIVE, "drive", "--can", "pacmod3", str(path), "--out", str(self.out),
             "--quiet", *(["--engage"] if engage else []), "--can-interface", "socketcand",
             "--can-channel", "can0", "--can-option", "host=127.0.0.1",
             "--can-option", f"port={self.hub.port}"],
            cwd=self.tmp, stdout=subprocess.PIPE, stderr=subprocess.PIPE)

    def kit_now(self) -> float:
        return time.monotonic() - self.start

    def records(self) -> tuple[list[dict], list[dict]]:
        lines = [json.loads(x) for x in self.log.read_text().splitlines()[1:] if x.strip()]
        return [x for x in lines if "cmd" in x], [x for x in lines if "truth" in x]

    def wait_moving(self, speed_mps: float = 1.0, within_s: float = 25.0) -> None:
        deadline = time.monotonic() + within_s
        while time.monotonic() < deadline:
            _, truths = self.records()
            if truths and truths[-1]["truth"]["speed_mps"] > speed_mps:
                return
            time.sleep(0.1)
        raise AssertionError("the vehicle never moved")

    def close(self) -> None:
        if self.drive is not None and self.drive.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.drive.pid, signal.SIGCONT)
            self.drive.kill()
            self.drive.wait(10)
        self.kit.terminate()
        self.kit.wait(10)
        self.hub.close()


@pytest.fixture
def rig(tmp_path):
    made: list[Rig] = []

    def make(*kit_args: str) -> Rig:
        made.append(Rig(tmp_path, kit_args))
        return made[-1]

    yield make
    for r in made:
        r.close()


def test_engage_brake_first_commands_at_30_hz_and_a_10_m_move_ends_within_0_2_m(rig) -> None:
    r = rig()
    r.run_drive({"distance_m": 10, "maxspeed_mps": 3, "curvature_1pm": 0}, 18.0)
    _, err = r.drive.communicate(timeout=90)
    assert r.drive.returncode == 0, err.decode()[-2000:]
    commands, truths = r.records()
    systems = [c for c in commands if c["cmd"] in SYSTEM_CMDS]
    first_on = next(i for i, c in enumerate(systems) if c["enable"])
    assert systems[first_on]["cmd"] == "BrakeCmd" and systems[first_on]["brake_ratio"] >= 0.5
    for name in SYSTEM_CMDS:   # each system saw enable=0 before its edge
        mine = [c for c in systems if c["cmd"] == name]
        edge = next(i for i, c in enumerate(mine) if c["enable"])
        assert edge >= 1 and not mine[edge - 1]["enable"], name
    last_edge_t = max(next(c["t"] for c in systems if c["cmd"] == n and c["enable"])
                      for n in SYSTEM_CMDS)
    throttle = [c for c in systems if c["cmd"] == "AccelCmd" and c["accel_ratio"] > 0]
    assert throttle and throttle[0]["t"] > last_edge_t, "no throttle before every system enabled"
    brake_t = [c["t"] for c in systems if c["cmd"] == "BrakeCmd"]
    gaps = [b - a for a, b in itertools.pairwise(brake_t)]
    assert max(gaps) < 0.1, f"a gap of {max(gaps):.3f} s reached the kit's timeout"
    rate_hz = (len(brake_t) - 1) / (brake_t[-1] - brake_t[0])   # the kit reads every 10 ms
    assert rate_hz == pytest.approx(30.0, abs=1.0)
    odometer = truths[-1]["truth"]["odometer_m"]
    assert odometer == pytest.approx(10.0, abs=0.2), err.decode()[-2000:]
    summary = json.loads((r.out / "summary.json").read_text())
    assert summary["link"]["engage_state"] == "disengaged"   # the drive's end let go, stopped
    assert [t["event"] for t in summary["link"]["transitions"]][-2:] == ["drive_end", "released"]
    can = json.loads((r.out / "can.json").read_text())
    assert can["dbc"]["sha256"] and can["python_can"]["interface"] == "socketcand"
    assert yaml.safe_load((r.out / "vehicle.yaml").read_text())["name"] == "lexus-rx450h"
    directions = set()
    with (r.out / "run.mcap").open("rb") as f:
        for _, _, message in make_reader(f).iter_messages(topics=["can/frames"]):
            directions |= {x["direction"] for x in json.loads(message.data)["frames"]}
    assert directions == {"rx", "tx"}, "raw frames both ways in run.mcap"
    assert not (r.out / "engage.json").exists(), "the endpoint goes with the drive"


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGSTOP], ids=["kill-9", "sigstop"])
def test_a_killed_or_stopped_drive_sends_nothing_and_the_kit_times_out(rig, sig) -> None:
    r = rig()
    r.run_drive({"distance_m": 30, "maxspeed_mps": 3, "curvature_1pm": 0}, 40.0)
    r.wait_moving()
    os.kill(r.drive.pid, sig)
    stopped_t = r.kit_now()
    time.sleep(1.0)
    if sig == signal.SIGSTOP:
        os.kill(r.drive.pid, signal.SIGCONT)
        time.sleep(1.5)
    commands, truths = r.records()
    in_flight_s = 0.05                  # frames already in the hub's sockets
    during = [c for c in commands if stopped_t + in_flight_s < c["t"] < stopped_t + 1.0]
    assert during == [], f"{len(during)} frames while the drive was {sig.name}"
    after = [t for t in truths if t["t"] > stopped_t + 0.15]
    assert after and all(t["truth"]["enabled"] == [] for t in after), \
        "the kit timed out and nothing re-enabled it"


def test_an_override_disengages_no_planner_command_re_engages_the_operator_does(
        rig, tmp_path) -> None:
    press = tmp_path / "press"
    r = rig("--press-file", str(press))
    r.run_drive({"distance_m": 40, "maxspeed_mps": 3, "curvature_1pm": 0}, 24.0)
    r.wait_moving()
    press.touch()                       # the safety driver presses the brake for a second
    pressed_t = r.kit_now()
    time.sleep(4.0)                     # released after 1 s; the planner's MOVE still stands
    commands, truths = r.records()
    after = [t for t in truths if pressed_t + 0.2 < t["t"]]
    assert after and all(t["truth"]["enabled"] == [] for t in after), "no re-engage by itself"
    assert not any(c.get("enable") for c in commands if c["t"] > pressed_t + 0.2)
    engaged = subprocess.run([OVERDRIVE, "engage", "--run", str(r.out)], capture_output=True,
                             timeout=30)
    assert engaged.returncode == 0, engaged.stdout + engaged.stderr
    engage_t = r.kit_now()
    time.sleep(0.5)
    commands, truths = r.records()
    assert set(truths[-1]["truth"]["enabled"]) == {"accel", "brake", "steering", "shift"}
    cleared = [c for c in commands if c["t"] > pressed_t + 1.0 and c.get("clear_override")]
    assert cleared and cleared[0]["t"] < engage_t, "re-engaged through the clear-override edge"


@pytest.mark.parametrize(("curvature_1pm", "silent"), [(0.05, "move"), (-0.05, "driving")],
                         ids=["right-move", "left-driving"])
def test_a_curve_turns_the_way_asked_and_a_silent_planner_stops_it_engaged(
        rig, curvature_1pm, silent) -> None:
    r = rig()
    r.run_drive({"distance_m": 40, "maxspeed_mps": 3, "curvature_1pm": curvature_1pm}, 16.0,
                extra=({"at_s": 10.0, "stall": {"node": silent, "for_s": 5.9}},))
    r.drive.communicate(timeout=90)
    commands, truths = r.records()
    brakes = [c for c in commands if c["cmd"] == "BrakeCmd"]
    last_on = max(i for i, c in enumerate(brakes) if c["enable"])
    assert brakes[last_on]["t"] > brakes[-1]["t"] - 0.2 and not brakes[-1]["enable"], \
        "engaged to the drive's end (its last frames hand the kit back, stopped)"
    engaged = [t for t in truths if len(t["truth"]["enabled"]) == 4]
    last = engaged[-1]
    assert last["t"] >= brakes[last_on]["t"] - 0.1
    # curvature positive turns right: heading clockwise (negative); negative turns left. The
    # heading turned is -curvature x the arc driven (the kit's truth; the start's steering
    # transition and the stop's are the 10 %)
    start = next(t for t in truths if t["truth"]["odometer_m"] > 0.0)
    turned_rad = last["truth"]["heading_rad"] - start["truth"]["heading_rad"]
    arc_m = last["truth"]["odometer_m"] - start["truth"]["odometer_m"]
    assert arc_m > 5.0
    assert turned_rad == pytest.approx(-curvature_1pm * arc_m, rel=0.10)
    assert abs(last["truth"]["speed_mps"]) < 0.05, "stopped while the planner was silent"
    assert last["truth"]["odometer_m"] < 35.0, "short of the MOVE's end"

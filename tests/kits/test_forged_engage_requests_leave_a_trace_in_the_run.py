"""Another local process sending engage requests without the drive's token: dropped unanswered
(held: nothing engages), and "counted" (docs/pacmod3-stack.md) - but the count must reach the
run folder, or the operator never learns that something tried to engage the vehicle."""

from __future__ import annotations

import json
import socket
import threading
import time
from pathlib import Path

import pytest
import yaml

from overdrive.run.drive_can import DEFAULT_VEHICLE, run_drive_can
from overdrive.runtime.can_edge import resolve_can_config
from overdrive.runtime.can_link import ENGAGE_FILE
from overdrive.scenario.schema import load_scenario
from overdrive.scenario.vehicles import KIT_VEHICLES
from tests.can.kit_thread import KitThread

pytestmark = pytest.mark.wallclock
FORGED = 5


def forge(run: Path, stop: threading.Event, sent: list[int]) -> None:
    """Wait for the drive's endpoint, then send FORGED requests with a wrong token."""
    path = run / ENGAGE_FILE
    while not stop.is_set():
        try:
            port = json.loads(path.read_text())["port"]
        except (OSError, ValueError, KeyError):
            time.sleep(0.02)
            continue
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for _ in range(FORGED):
                s.sendto(json.dumps({"token": "0" * 32, "act": "engage"}).encode(),
                         ("127.0.0.1", port))
                sent.append(1)
        return


def counts(value, path=""):
    """Every (key path, integer) in ``value``."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from counts(v, f"{path}.{k}")
    elif isinstance(value, int) and not isinstance(value, bool):
        yield path, value


def test_forged_engage_requests_are_counted_in_the_summary(tmp_path) -> None:
    """Measured 2026-11-26: 5 requests with a wrong token during a 3 s drive waiting
    disengaged: the kit stayed disabled (held), and summary.json's link has no count that
    mentions engage requests or the endpoint (`grep -rn '\\.refused' src/` finds no reader)."""
    scenario = tmp_path / "wait.yaml"
    scenario.write_text(yaml.safe_dump({"name": "wait", "start": "ready", "seed": 1,
                                        "duration_s": 3.0, "events": []}))
    run, stop, sent = tmp_path / "run", threading.Event(), []
    thread = threading.Thread(target=forge, args=(run, stop, sent))
    thread.start()
    try:
        with KitThread(KIT_VEHICLES[DEFAULT_VEHICLE], "forged-engage") as kit:
            result = run_drive_can(load_scenario(scenario),
                                   resolve_can_config(interface="virtual",
                                                      channel="forged-engage"),
                                   run, plot=False)
            truth = kit.truth()
    finally:
        stop.set()
        thread.join()
    assert len(sent) == FORGED and truth.enabled == (), "held: nothing engaged"
    found = [(k, v) for k, v in counts(result.summary["link"])
             if v == FORGED and any(w in k for w in ("request", "endpoint", "token", "forged"))]
    assert found, f"no trace of {FORGED} forged engage requests in link"

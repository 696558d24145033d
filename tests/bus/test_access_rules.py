"""Per-run credentials and access rules (issue 18), without processes: what is generated."""

from __future__ import annotations

import json
import stat
from pathlib import Path

import pytest

from overdrive.bus.access import (
    GATE_USER,
    LAUNCHER_USER,
    TOOL_TOPICS,
    TOOL_USER,
    RunAccess,
    acl,
    count_refused_links,
    owners,
    read_tool_credentials,
)
from overdrive.bus.tool_gate import TOOL_SENDER, ToolPolicy
from overdrive.bus.zenoh_bus import PUBLISHERS
from overdrive.messages import Notice, PedalCommand, SetSpeed, Topic
from overdrive.run.launch import stack_registry

NODES = ("vehicle", "speed", "driving", "move")
PEDALS = PedalCommand(throttle_pct=100.0, brake_pct=0.0, source="speed")


def _denied(rules: dict, user: str) -> set[str]:
    by_id = {r["id"]: r for r in rules["rules"]}
    policy = next(p for p in rules["policies"] if p["subjects"] == [user])
    return {k for rid in policy["rules"] if "put" in by_id[rid]["messages"]
            for k in by_id[rid]["key_exprs"]}


@pytest.mark.parametrize("user", [*NODES, LAUNCHER_USER, GATE_USER])
def test_each_user_may_put_exactly_the_topics_it_owns(user: str) -> None:
    rules = acl([*NODES, LAUNCHER_USER, GATE_USER])
    denied = _denied(rules, user)
    for topic, allowed in owners().items():
        assert (f"overdrive/*/{topic}" in denied) is (user not in allowed), topic
    assert rules["default_permission"] == "allow"   # only links the process dialled itself


def test_the_gate_and_tools_may_write_no_command_topic() -> None:
    denied = _denied(acl([*NODES, LAUNCHER_USER, GATE_USER]), GATE_USER)
    assert {t for t, who in PUBLISHERS.items() if GATE_USER in who} == {Topic.TICK}  # its liveness
    assert {f"overdrive/*/{t}" for t in PUBLISHERS if t != Topic.TICK} <= denied
    assert {Topic.NOTICE} == TOOL_TOPICS and Topic.NOTICE not in PUBLISHERS


def test_credentials_are_per_run_owner_only_and_readable_by_tools(tmp_path: Path) -> None:
    tokens = iter(f"pw{i}" for i in range(100))
    access = RunAccess.generate(tmp_path / "access", NODES, lambda: next(tokens))
    assert set(access.passwords) == {*NODES, LAUNCHER_USER, GATE_USER, TOOL_USER}
    assert len(set(access.passwords.values())) == len(access.passwords), "one secret per user"
    access.write("tcp/127.0.0.1:7447", "ego")
    assert stat.S_IMODE(access.folder.stat().st_mode) == 0o700
    for path in access.folder.iterdir():
        assert stat.S_IMODE(path.stat().st_mode) == 0o600, path
    mesh_users = (access.folder / "users.txt").read_text()
    assert f"{TOOL_USER}:" not in mesh_users, "a tool's password does not open the mesh"
    assert (access.folder / "tools.txt").read_text().strip() == f"tool:{access.password(TOOL_USER)}"
    config = json.loads(access.mesh_config.read_text())
    assert config["access_control"]["enabled"] is True
    assert read_tool_credentials(access.folder) == {
        "endpoint": "tcp/127.0.0.1:7447", "vehicle": "ego", "user": TOOL_USER,
        "password": access.password(TOOL_USER)}
    with pytest.raises(FileNotFoundError):
        read_tool_credentials(tmp_path / "elsewhere")


def test_tool_policy_admits_notes_and_denies_and_counts_everything_else() -> None:
    registry = stack_registry()
    policy = ToolPolicy(registry, "ego")
    note = Notice(kind="note", source="cli", reason="hi")
    admitted = policy.admit("overdrive/ego/events", registry.encode(note, "speed"), 1.0)
    assert admitted is not None and admitted[0] == "overdrive/ego/events"
    assert registry.decode(admitted[1]) == (TOOL_SENDER, note), "claimed names are not passed on"
    spss = SetSpeed(speed_mps=18.0, accel_mps2=3.0, gear="drive", state="run")
    attempts = [("overdrive/ego/vehicle/pedals", registry.encode(PEDALS, "speed")),
                ("overdrive/ego/speed/set_speed", registry.encode(spss, "driving")),
                ("overdrive/ego/vehicle/pedals", b"\x00junk"),
                ("overdrive/other/vehicle/pedals", registry.encode(PEDALS, "speed")),
                ("overdrive/ego/events", registry.encode(PEDALS, "speed"))]   # wrong type
    assert [policy.admit(k, f, 1.0) for k, f in attempts] == [None] * len(attempts)
    report = policy.report()
    assert report["admitted"] == 1 and report["denied_total"] == len(attempts)
    assert report["denied"]["vehicle/pedals as 'speed'"] == 1
    assert report["denied"]["speed/set_speed as 'driving'"] == 1
    assert report["denied"]["vehicle/pedals: malformed"] == 1


def test_refused_links_are_counted_from_zenoh_logs_with_or_without_colour() -> None:
    log = ("\x1b[2m2026\x1b[0m DEBUG acc-0 zenoh_transport::unicast::establishment::accept: "
           "UsrPwd extension - Recv InitSyn. Expected extension. at x\n"
           "DEBUG accept: UsrPwd extension - Recv OpenSyn. Invalid password. at y\n"
           "DEBUG accept: New transport link accepted from a to b\n")
    assert count_refused_links(log) == 2
    assert count_refused_links("") == 0


LOCKED_DOWN = Path(__file__).resolve().parents[2] / "config" / "zenoh-locked-down.json5"
EXAMPLE_USERS = Path(__file__).resolve().parents[2] / "config" / "zenoh-users.example.txt"


@pytest.mark.parametrize("user", [line.split(":")[0] for line in
                                  EXAMPLE_USERS.read_text(encoding="utf-8").split()])
def test_the_shipped_locked_down_config_denies_each_user_exactly_what_it_does_not_own(
        user: str) -> None:
    """config/zenoh-locked-down.json5 is written from ``PUBLISHERS`` (``owners``): every owned
    topic a user does not own (liveness ticks and clock reports included) is denied to it, and
    nothing it owns."""
    import zenoh

    rules = json.loads(zenoh.Config.from_file(str(LOCKED_DOWN)).get_json("access_control"))
    expected = {f"overdrive/*/{topic}" for topic, who in owners().items() if user not in who}
    assert _denied(rules, user) == expected

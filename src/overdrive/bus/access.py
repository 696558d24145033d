"""Who may join and command a multi-process run (issue 18): per-run credentials and rules.

``overdrive launch`` generates, for every run, a password per process (``RunAccess``), a Zenoh
configuration with user/password authentication and access-control rules (``acl``) derived
from ``PUBLISHERS``, and a separate password for tools (``overdrive pub``/``echo``). Tools never
join the mesh: they attach to the run's tool gate (``overdrive.bus.tool_gate``), which lets
them read every topic and write only ``TOOL_TOPICS``; everything else is denied and counted.

Zenoh's user/password identifies the side that *dials* a link; the launcher orders the mesh so
that command senders dial command receivers (docs/multiprocess.md), so every link that can
carry a command into a process is authenticated there, and each user may put only the keys it
owns. A link with no user name is one the process dialled itself, to an endpoint the launcher
gave it: that is the rules' default (allow). Pure data and text: files are written by the
launcher, passwords come from the ``token`` function it passes (``secrets.token_urlsafe``).
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from overdrive.bus.zenoh_bus import ALIVE, KEY_ROOT, PUBLISHERS
from overdrive.messages import Topic

LAUNCHER_USER = "scenario"        # the launcher's session: scenario player, recorder, clock
GATE_USER = "gate"                # the tool gate's mesh session
TOOL_USER = "tool"                # overdrive pub / echo, at the gate only
TOOL_TOPICS = frozenset({Topic.NOTICE})
"""What a tool may write into a run: notes on ``events``. Nothing that moves the vehicle."""
CLOCK_TOPIC = "launch/clock"      # launch.CLOCK_TOPIC (not imported: launch imports this module)

MESH_USERS_FILE, TOOL_USERS_FILE = "users.txt", "tools.txt"
MESH_CONFIG_FILE, TOOL_FILE = "zenoh.json5", "tool.json"

LOG_FILTER = "error,zenoh_transport::unicast::establishment::accept=debug"
"""Zenoh log directives for run processes: errors, plus the accept side of link set-up, which
logs every link refused for missing or wrong credentials (counted from the node logs)."""
_REFUSED = re.compile(r"UsrPwd extension - Recv (InitSyn|OpenSyn)\. (Expected extension|Invalid)")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def owners() -> dict[str, frozenset[str]]:
    """``PUBLISHERS`` plus the launch clock (the launcher's): who may put each owned topic."""
    return {**PUBLISHERS, CLOCK_TOPIC: frozenset({LAUNCHER_USER})}


def acl(users: Iterable[str]) -> dict[str, Any]:
    """Zenoh ``access_control`` for ``users``: each may put (and delete) only the owned keys
    whose owners include it; liveliness tokens (``_alive``) only from node processes."""
    topics = owners()
    users = sorted(set(users))
    rules: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    subjects = [{"id": u, "usernames": [u]} for u in users]
    for topic in sorted(topics):
        rules.append({"id": f"deny_{_rule_id(topic)}", "permission": "deny", "flows": ["ingress"],
                      "messages": ["put", "delete"],
                      "key_exprs": [f"{KEY_ROOT}/*/{topic}"]})
    rules.append({"id": "deny_alive", "permission": "deny", "flows": ["ingress"],
                  "messages": ["liveliness_token"], "key_exprs": [f"{KEY_ROOT}/*/{ALIVE}/**"]})
    for user in users:
        denied = [f"deny_{_rule_id(t)}" for t in sorted(topics) if user not in topics[t]]
        if user in (GATE_USER, LAUNCHER_USER):
            denied.append("deny_alive")
        policies.append({"rules": denied, "subjects": [user]})
    return {"enabled": True, "default_permission": "allow", "rules": rules,
            "subjects": subjects, "policies": policies}


def _rule_id(topic: str) -> str:
    return topic.replace("/", "_")


def count_refused_links(log_text: str) -> int:
    """Links a run process refused for missing or wrong credentials, from its Zenoh log."""
    return len(_REFUSED.findall(_ANSI.sub("", log_text)))


@dataclass(frozen=True)
class RunAccess:
    """One run's credentials: a password per mesh user and one for tools, kept in ``folder``."""

    folder: Path
    passwords: dict[str, str]

    @classmethod
    def generate(cls, folder: Path, users: Iterable[str], token: Callable[[], str]) -> RunAccess:
        names = sorted({*users, LAUNCHER_USER, GATE_USER, TOOL_USER})
        return cls(Path(folder), {name: token() for name in names})

    def password(self, user: str) -> str:
        return self.passwords[user]

    @property
    def mesh_config(self) -> Path:
        return self.folder / MESH_CONFIG_FILE

    @property
    def tool_users(self) -> Path:
        return self.folder / TOOL_USERS_FILE

    @property
    def tool_file(self) -> Path:
        return self.folder / TOOL_FILE

    def write(self, tool_endpoint: str, vehicle: str) -> None:
        """Write the dictionaries, the mesh config and the tool's credentials, owner-only."""
        self.folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        os.chmod(self.folder, 0o700)
        mesh = {u: p for u, p in self.passwords.items() if u != TOOL_USER}
        config = {"transport": {"auth": {"usrpwd": {
            "dictionary_file": str(self.folder / MESH_USERS_FILE)}}},
            "access_control": acl(mesh)}
        tool = {"endpoint": tool_endpoint, "vehicle": vehicle, "user": TOOL_USER,
                "password": self.passwords[TOOL_USER]}
        for name, text in ((MESH_USERS_FILE, _dictionary(mesh)),
                           (TOOL_USERS_FILE, _dictionary({TOOL_USER: self.passwords[TOOL_USER]})),
                           (MESH_CONFIG_FILE, json.dumps(config, indent=2)),
                           (TOOL_FILE, json.dumps(tool, indent=2))):
            path = self.folder / name
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text + "\n")


def _dictionary(passwords: dict[str, str]) -> str:
    return "\n".join(f"{user}:{password}" for user, password in sorted(passwords.items()))


def read_tool_credentials(run_dir: str | Path) -> dict[str, str]:
    """The tool credentials a running launch wrote under ``RUN/nodes/access`` (or a folder)."""
    run_dir = Path(run_dir)
    for path in (run_dir / "nodes" / "access" / TOOL_FILE, run_dir / TOOL_FILE):
        if path.is_file():
            data = json.loads(path.read_text(encoding="utf-8"))
            return {k: str(data[k]) for k in ("endpoint", "vehicle", "user", "password")}
    raise FileNotFoundError(f"{run_dir}: no {TOOL_FILE} (is the run still going?)")


__all__ = ["GATE_USER", "LAUNCHER_USER", "LOG_FILTER", "TOOL_TOPICS", "TOOL_USER", "RunAccess",
           "acl", "count_refused_links", "owners", "read_tool_credentials"]

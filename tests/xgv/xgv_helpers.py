"""Helpers for the XGV tests: a sans-IO peer talking to an ``XgvSimulator`` without sockets."""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from typing import Any

import msgspec

from overdrive.jaus import Header, JausId, Message, decode_datagram, encode_datagram
from overdrive.scenario.vehicles import PRESETS
from overdrive.vehicle.xgv import XgvSimulator

CLIENT = JausId(1, 2, 4, 1)
OTHER = JausId(1, 3, 4, 1)
PD = JausId(1, 1, 33, 1)
MPD = JausId(1, 1, 10, 1)
NM = JausId(1, 1, 1, 1)
PERIOD_S = 0.01


def make_sim(ready: bool = True, **kwargs: Any) -> XgvSimulator:
    return XgvSimulator(PRESETS["escape-hybrid"], ready=ready, **kwargs)


class Peer:
    """A JAUS client at ``address`` with id ``jaus_id``; collects what the simulator sends it."""

    def __init__(self, sim: XgvSimulator, jaus_id: JausId = CLIENT,
                 address: tuple[str, int] = ("127.0.0.1", 40000),
                 mail: dict[tuple[str, int], list[Message]] | None = None) -> None:
        self.sim, self.jaus_id, self.address = sim, jaus_id, address
        self.mail = mail if mail is not None else {}
        self.inbox = self.mail.setdefault(address, [])
        self.now_s = 0.0

    def send(self, *messages: Message, to: JausId = PD, service: bool = False) -> list[Message]:
        framed = [msgspec.structs.replace(m, header=Header(destination=to, source=self.jaus_id,
                                                          service_connection=service))
                  for m in messages]
        replies = self._take(self.sim.receive(encode_datagram(framed), self.address, self.now_s))
        return replies

    def step(self, n: int = 1) -> list[Message]:
        got: list[Message] = []
        for _ in range(n):
            got += self._take(self.sim.step(self.now_s), everyone=True)
            self.now_s = round(self.now_s + PERIOD_S, 9)
        return got

    def _take(self, out: list[tuple[bytes, tuple[str, int]]], everyone: bool = False) -> list[Message]:
        mine: list[Message] = []
        for data, address in out:
            messages = decode_datagram(data)
            self.mail.setdefault(address, []).extend(messages)
            if address == self.address:
                mine += messages
        return mine

    def of(self, cls: type[Message]) -> list[Any]:
        return [m for m in self.inbox if isinstance(m, cls)]


READY_SCENARIO = {"name": "udp", "start": "ready", "duration_s": 60}
SERVE_S = 60.0


def ready_scenario() -> Any:
    from overdrive.scenario.schema import parse_scenario

    return parse_scenario(READY_SCENARIO, "<test>")


@contextlib.contextmanager
def serving(server: Any) -> Iterator[Any]:
    """``server`` (an ``XgvServer``) serving on a thread for at most ``SERVE_S``; stopped,
    joined and closed on exit."""
    thread = threading.Thread(target=server.serve, kwargs={"duration_s": SERVE_S}, daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.stop()
        thread.join(timeout=5.0)
        server.close()

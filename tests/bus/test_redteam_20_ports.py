"""Red team (issue 20): ``free_ports`` on a host whose ephemeral range covers most, not all,
of 20000-32767 found too few ports and the launch failed with a traceback; it now falls back to
``bind(0)``."""

from __future__ import annotations

import pytest

from overdrive.runtime import ports as ports_mod


@pytest.mark.parametrize("eph", [(20010, 65535), (20001, 60999), (20000, 32766), (1024, 65535)])
def test_free_ports_finds_ports_whatever_the_ephemeral_range(monkeypatch, eph) -> None:
    monkeypatch.setattr(ports_mod, "ephemeral_range", lambda: eph)
    ports = ports_mod.free_ports(5)      # a launch of four nodes and a gate
    assert len(set(ports)) == 5

"""The fault display on a console: one line each time the speed server's ``Display`` text
changes (seed 001's LED sign, for whoever watches a wall-clock run: ``overdrive drive``,
``overdrive launch``). A bus tap: it never feeds anything back into the stack."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from overdrive.messages import Display, Topic, sign_text


class DisplayLines:
    """Calls ``write`` with one line per change of the displayed text (the periodic refresh
    of an unchanged text prints nothing); ``set_time`` stamps the lines with the run's time."""

    def __init__(self, write: Callable[[str], Any]) -> None:
        self.write = write
        self.now_s = 0.0
        self.text: str | None = None   # None: nothing displayed yet (a blank first is not printed)
        self.lines = 0

    def set_time(self, now_s: float) -> None:
        self.now_s = now_s

    def observe(self, topic: str, msg: Any) -> None:
        if topic != Topic.DISPLAY or not isinstance(msg, Display) or msg.text == self.text:
            return
        first, self.text = self.text is None, msg.text
        if first and not msg.text:
            return
        # bounded and printable whoever sent it (a replayed or foreign Display): one short line
        shown = f"fault {msg.code}: {sign_text(msg.text)}" if msg.text else "(clear)"
        self.write(f"display {self.now_s:8.2f} s  {shown}")
        self.lines += 1


__all__ = ["DisplayLines"]

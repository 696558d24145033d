"""Dispatching a server's inputs by message type, shared by the move and speed servers."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

Handler = Callable[[float, Any, list], None]
"""``handler(now_s, msg, out)``: reads one input, may append to the period's outputs."""


class TypeDispatch:
    """Calls the handler of a message's type: the first listed base class the type derives from,
    else ``default``; resolved once per concrete type (a subclass finds its base's handler)."""

    __slots__ = ("_by_type", "_default", "_table")

    def __init__(self, table: Sequence[tuple[type, Handler]], default: Handler) -> None:
        self._table = tuple(table)
        self._default = default
        self._by_type: dict[type, Handler] = {}

    def handler_for(self, cls: type) -> Handler:
        handler = self._by_type.get(cls)
        if handler is None:
            handler = next((h for base, h in self._table if issubclass(cls, base)), self._default)
            self._by_type[cls] = handler
        return handler

    def __call__(self, now_s: float, msg: Any, out: list) -> None:
        handler = self._by_type.get(type(msg))    # every input of every period: one lookup
        if handler is None:
            handler = self.handler_for(type(msg))
        handler(now_s, msg, out)

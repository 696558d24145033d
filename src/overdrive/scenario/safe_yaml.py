"""Reading hostile YAML and JSON input files with bounded size, time and memory.

``yaml.safe_load`` is safe from code execution but not from hostile shapes: an alias bomb
expands to billions of nodes for whoever walks the result, deep nesting overflows the
recursive composer, and duplicate keys are silently merged (the last wins). This module reads
the parser's event stream into plain dicts and lists itself, without recursion, and enforces
the limits below. The result is a tree: an alias is expanded into a copy of its anchor's
value, charged to the node budget, so every later walk is linear in ``MAX_NODES``.
"""

from __future__ import annotations

import copy
import json
import os
import re
import stat
from pathlib import Path
from typing import Any

import yaml

MAX_FILE_BYTES = 1 << 20
"""1 MiB: the largest shipped scenario is ~8 KB; 1,000 events take ~50 KB."""
MAX_JSON_BYTES = 32 << 20
"""32 MiB: the launcher's JSON copy of a scenario writes ~25 nulls per event (~450 bytes), so
a YAML file within the limits (<= ~20,000 events) stays below ~10 MB as JSON."""
MAX_DEPTH = 32
"""Nesting levels of mappings and lists; a scenario needs 6 (events[i].actuator.brake...)."""
MAX_NODES = 100_000
"""Scalars (keys too), mappings and lists, an alias counted as the nodes it stands for; an
event such as ``{at_s: 1, engine: "on"}`` is 5, so ~20,000 events fit."""

_MERGE_TAG = "tag:yaml.org,2002:merge"
_FLOAT_TAG = "tag:yaml.org,2002:float"
MAX_NUMBER_CHARS = 100
"""Longer plain numbers are refused unread: Python refuses 4,300-digit ints, nobody needs 100."""


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """The safe loader (libyaml's when built with it: ~10x faster), reading ``1e3`` and
    ``1.0e308`` as numbers as YAML 1.2 and JSON do (YAML 1.1 wants ``1.0e+3``: a string)."""


class _PyLoader(yaml.SafeLoader):
    """The pure-Python safe loader with the same resolvers: the second reader of a file that
    libyaml refused for its own nesting limit (below)."""


_LIBYAML_NESTING = "exceeded maximum nesting depth"
"""libyaml >= 0.2.5 (bundled in PyYAML 6.0.2+ wheels) scans a flow collection's tokens ahead
of its events to resolve simple keys, so it stops at its own nesting limit (1,000 levels)
before the loader sees one event; the pure-Python scanner stops looking ahead after 1,024
characters and hands out the events, so the project's ``MAX_DEPTH`` names the field."""

for _cls in (_Loader, _PyLoader):
    _cls.add_implicit_resolver(
        _FLOAT_TAG, re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
        list("-+0123456789."))


def one_line(text: str) -> str:
    """``text`` with line breaks and other control characters escaped (``\\n``, ``\\x1b``): a
    key or a path from a hostile file can neither split an error line nor drive the terminal."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class InputError(ValueError):
    """A file that cannot be read as data: ``field`` is the path inside it ("" for the file)."""

    def __init__(self, field: str, reason: str) -> None:
        self.field, self.reason = field, reason
        super().__init__(f"{field}: {reason}" if field else reason)


def read_text(path: Path, max_bytes: int = MAX_FILE_BYTES) -> str:
    """The file's text: a regular file of at most ``max_bytes`` bytes, strict UTF-8.

    Only regular files: a FIFO would block the open, and /dev/zero never ends.
    """
    try:
        info = os.stat(path)
    except OSError as exc:
        raise InputError("", f"cannot read: {exc.strerror or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        kind = "a directory" if stat.S_ISDIR(info.st_mode) else "not a regular file"
        raise InputError("", f"cannot read: {kind}")
    try:
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
    except OSError as exc:
        raise InputError("", f"cannot read: {exc.strerror or exc}") from None
    if len(data) > max_bytes:
        raise InputError("", f"file larger than the limit of {max_bytes} bytes")
    return decode_utf8(data)


def decode_utf8(data: bytes) -> str:
    """Strict UTF-8 (a leading BOM is kept: YAML skips it), or ``InputError`` with the line."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError("", f"not UTF-8: byte 0x{data[exc.start]:02x} at line {line}") from None


class _Open:
    """A mapping or list being filled, with where it stands in the document."""

    __slots__ = ("anchor", "first_node", "height", "key", "value")

    def __init__(self, value: dict | list, anchor: str | None, first_node: int) -> None:
        self.value, self.anchor, self.first_node = value, anchor, first_node
        self.key: Any = _NO_KEY
        self.height = 1     # nesting levels of this collection and what it holds so far


_NO_KEY = object()


def _path(stack: list[_Open]) -> str:
    """The field path of the next value, e.g. ``events[2].move.distance_m``."""
    out = ""
    for frame in stack:
        if isinstance(frame.value, list):
            out += f"[{len(frame.value)}]"
        elif frame.key is not _NO_KEY:
            out += f".{frame.key}" if out else str(frame.key)
    return out


def load_yaml(text: str) -> Any:
    """One YAML document as plain data, or ``InputError`` naming the field and the problem.

    Rejected: explicit tags (``!!binary``, ``!!python/object``: a scenario needs none), merge
    keys (``<<``), duplicate keys, non-scalar keys, aliases to an unfinished (recursive)
    anchor, more than one document, nesting deeper than ``MAX_DEPTH`` and more than
    ``MAX_NODES`` nodes after alias expansion. A file that libyaml refuses for its own
    nesting limit is read again by the pure-Python parser, so the message is the same (the
    field path and ``MAX_DEPTH``) whichever parser and version the install has.
    """
    try:
        return _load_yaml(text, _Loader)
    except _LibyamlNesting:
        return _load_yaml(text, _PyLoader)


class _LibyamlNesting(Exception):
    """libyaml stopped at its own nesting limit before handing out the events."""


def _load_yaml(text: str, loader_class: type) -> Any:
    """``load_yaml`` with one parser: ``_LibyamlNesting`` when it is libyaml's limit."""
    stack: list[_Open] = []
    anchors: dict[str, tuple[Any, int, int]] = {}     # name: (value, nodes, nesting levels)
    nodes = documents = 0
    root: Any = None

    def fail(reason: str, event: Any) -> InputError:
        line = f" (line {event.start_mark.line + 1})" if event.start_mark is not None else ""
        return InputError(_path(stack), reason + line)

    def add(value: Any, event: Any, height: int = 0) -> None:
        nonlocal root
        if not stack:
            root = value
            return
        frame = stack[-1]
        frame.height = max(frame.height, height + 1)
        if isinstance(frame.value, list):
            frame.value.append(value)
        elif frame.key is _NO_KEY:
            if isinstance(value, (dict, list)):
                raise fail("a mapping key must be a plain value, not a mapping or list", event)
            if value in frame.value:
                frame.key = value
                raise fail(f"duplicate key {value!r}", event)
            frame.key = value
        else:
            frame.value[frame.key] = value
            frame.key = _NO_KEY

    loader = None
    try:
        loader = loader_class(text)     # the pure-Python reader checks every character here
        while not isinstance(event := loader.get_event(), yaml.StreamEndEvent):
            if isinstance(event, (yaml.StreamStartEvent, yaml.DocumentEndEvent)):
                continue
            if isinstance(event, yaml.DocumentStartEvent):
                documents += 1
                if documents > 1:
                    raise fail("more than one YAML document", event)
                continue
            if isinstance(event, yaml.CollectionEndEvent):
                frame = stack.pop()
                if frame.anchor is not None:
                    anchors[frame.anchor] = (frame.value, nodes - frame.first_node + 1,
                                             frame.height)
                add(frame.value, event, frame.height)
                continue
            if getattr(event, "tag", None) is not None:
                raise fail(f"YAML tags ({event.tag}) are not allowed", event)
            alias = isinstance(event, yaml.AliasEvent)
            if alias and event.anchor not in anchors:
                raise fail(f"alias *{event.anchor} names no finished anchor "
                           "(undefined, or used inside itself)", event)
            nodes += anchors[event.anchor][1] if alias else 1
            if nodes > MAX_NODES:
                raise fail(f"more than {MAX_NODES} values (an alias counts as all it stands for)",
                           event)
            if alias:
                value, _, height = anchors[event.anchor]
                if len(stack) + height > MAX_DEPTH:    # an alias chain nests as deep as it expands
                    raise fail(f"nested deeper than {MAX_DEPTH} levels", event)
                add(copy.deepcopy(value), event, height)
            elif isinstance(event, yaml.ScalarEvent):
                value = _scalar(loader, event, fail)
                if event.anchor is not None:
                    anchors[event.anchor] = (value, 1, 0)
                add(value, event)
            elif len(stack) >= MAX_DEPTH:
                raise fail(f"nested deeper than {MAX_DEPTH} levels", event)
            else:
                container: dict | list = {} if isinstance(event, yaml.MappingStartEvent) else []
                stack.append(_Open(container, event.anchor, nodes))
    except yaml.YAMLError as exc:
        if loader_class is not _PyLoader and _LIBYAML_NESTING in str(exc):
            raise _LibyamlNesting from None
        raise InputError("", f"not valid YAML: {exc}".replace("\n", " ")) from None
    finally:
        if loader is not None:
            loader.dispose()
    return root


def _scalar(loader: Any, event: yaml.ScalarEvent, fail: Any) -> Any:
    """The value of a plain or quoted scalar as YAML 1.1 resolves it (quoted: always a string)."""
    tag = loader.resolve(yaml.ScalarNode, event.value, event.implicit)
    if tag == _MERGE_TAG:
        raise fail("merge keys (<<) are not allowed", event)
    constructor = loader.yaml_constructors.get(tag)
    if constructor is None:
        raise fail(f"unsupported value {event.value!r}", event)
    if tag in (_FLOAT_TAG, "tag:yaml.org,2002:int") and len(event.value) > MAX_NUMBER_CHARS:
        raise fail(f"a number of {len(event.value)} characters (at most {MAX_NUMBER_CHARS})", event)
    node = yaml.ScalarNode(tag, event.value, event.start_mark, event.end_mark, event.style)
    try:
        return constructor(loader, node)
    except ValueError as exc:   # a 13th month
        raise fail(f"cannot read {event.value[:40]!r}: {exc}", event) from None


def load_json(text: str) -> Any:
    """A JSON document as plain data; duplicate keys and deep nesting rejected (NaN and
    Infinity load as floats: the scenario check names their field)."""

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key, value in items:
            if key in out:
                raise InputError("", f"duplicate key {key!r}")
            out[key] = value
        return out

    try:
        return json.loads(text, object_pairs_hook=pairs)
    except RecursionError:
        raise InputError("", f"nested deeper than {MAX_DEPTH} levels") from None
    except InputError:
        raise
    except ValueError as exc:
        raise InputError("", f"not valid JSON: {exc}") from None

"""Payload layouts: a record's fields as wire types, compiled into straight-line code.

A layout is a list of ``(field name, Wire)``; :class:`FixedLayout` packs them all in order,
:class:`PresenceLayout` packs a presence vector then the fields whose bit is set (bit i =
field i, reference §5; undefined bits are ignored on decode). Each layout compiles its encoder and decoder into generated
straight-line functions (one pair per presence vector for presence layouts) with the
scaled-integer arithmetic of :class:`~overdrive.jaus.codec.ScaledInt` inlined: per-field
calls were most of the cost of a Set Wrench Effort round trip, and the generated form is
about twice as fast (bench/bench_jaus.py). The generated source is kept in ``source`` for
inspection; its arithmetic is ScaledInt's expressions, in the same order (a test checks they
agree).

Errors: the generated encoder fails fast; the layout then re-checks field by field with the
plain converters to raise a :class:`JausEncodeError` naming the field.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from typing import Any, Final

from overdrive.jaus.codec import JausDecodeError, JausEncodeError, ScaledInt

_INT_RANGES: Final = {
    "B": (0, 0xFF),
    "H": (0, 0xFFFF),
    "I": (0, 0xFFFFFFFF),
    "i": (-(2**31), 2**31 - 1),
}
ENCODE_FAILURES: Final = (JausEncodeError, TypeError, ValueError, OverflowError, struct.error)
"""What a generated encoder may raise on a bad value, before it is turned into a
JausEncodeError that names the field."""


class Wire:
    """How one field goes on the wire: a struct format character and two conversions.

    ``to_raw`` (value -> int, raising JausEncodeError) and ``from_raw`` (int -> value) are
    None when the field is the raw integer itself; struct then checks its range.
    """

    __slots__ = ("fmt", "from_raw", "to_raw")

    def __init__(
        self,
        fmt: str,
        to_raw: Callable[[Any], int] | None = None,
        from_raw: Callable[[int], Any] | None = None,
    ) -> None:
        self.fmt = fmt
        self.to_raw = to_raw
        self.from_raw = from_raw

    def check(self, value: Any) -> None:
        """Raise JausEncodeError if ``value`` cannot be encoded (the slow, precise path)."""
        if self.to_raw is not None:
            self.to_raw(value)
            return
        low, high = _INT_RANGES[self.fmt]
        if not isinstance(value, int) or not low <= value <= high:
            raise JausEncodeError(f"must be an integer {low}..{high}, got {value!r}")

    def encode_source(self, var: str, ns: dict[str, Any], tag: str) -> list[str]:
        """Lines turning local ``var`` from a value into its raw integer."""
        if self.to_raw is None:
            return []
        ns[f"to_raw_{tag}"] = self.to_raw
        return [f"{var} = to_raw_{tag}({var})"]

    def decode_source(self, var: str, ns: dict[str, Any], tag: str) -> list[str]:
        """Lines turning local ``var`` from a raw integer into its value."""
        if self.from_raw is None:
            return []
        ns[f"from_raw_{tag}"] = self.from_raw
        return [f"{var} = from_raw_{tag}({var})"]


class ScaledWire(Wire):
    """A :class:`ScaledInt` field, inlined into the generated code with its constants as
    literals (``repr`` of a float reads back as the same double)."""

    __slots__ = ("scaled",)

    def __init__(self, scaled: ScaledInt) -> None:
        super().__init__(scaled.fmt, scaled.to_raw, scaled.from_raw)
        self.scaled = scaled

    def encode_source(self, var: str, ns: dict[str, Any], tag: str) -> list[str]:
        s = self.scaled
        ns[f"to_raw_{tag}"] = s.to_raw
        # in range: the last line of ScaledInt.to_raw; out of range, NaN or infinite: the
        # whole ScaledInt.to_raw, which clamps or raises
        # a zero bias is left out: v - 0.0 and v + 0.0 are v (bar the sign of -0.0, which
        # neither the truncation nor the clamp can see)
        offset = f"({var} - ({s.bias!r}))" if s.bias else var
        return [
            f"if {s.lo!r} <= {var} <= {s.hi!r}:",
            f"    {var} = int({offset} / {s.scale!r} + 0.5)",
            "else:",
            f"    {var} = to_raw_{tag}({var})",
        ]

    def decode_source(self, var: str, ns: dict[str, Any], tag: str) -> list[str]:
        s = self.scaled
        # ScaledInt.from_raw: OpenJAUS's raw * scale + bias, then the clamp
        return [
            f"{var} = {var} * {s.scale!r}" + (f" + ({s.bias!r})" if s.bias else ""),
            f"if not {s.lo!r} <= {var} <= {s.hi!r}:",
            f"    {var} = {s.lo!r} if {var} < {s.lo!r} else {s.hi!r}",
        ]


def _compile(name: str, lines: list[str], ns: dict[str, Any]) -> tuple[Callable[..., Any], str]:
    source = "\n".join(lines)
    namespace = {"JausDecodeError": JausDecodeError, **ns}
    exec(compile(source, f"<jaus layout {name}>", "exec"), namespace)
    return namespace[name], source


def _indent(lines: list[str]) -> list[str]:
    return ["    " + line for line in lines]


def _targets(names: Sequence[str]) -> str:
    """An assignment target / tuple display for ``names`` (``a, b,`` form, valid for one)."""
    return "".join(f"{name}, " for name in names)


def _encoder(
    signature: str, fields: Sequence[tuple[int, Wire]], pack: Callable[..., bytes], *lead: int
) -> tuple[Callable[..., bytes], str]:
    """``def encode(signature)``: convert each field ``v<i>`` then pack ``lead`` and them."""
    ns: dict[str, Any] = {"pack": pack}
    lines = [f"def encode({signature}):"]
    if signature == "values" and fields:
        lines.append(f"    {_targets(f'v{i}' for i, _ in fields)}= values[:{len(fields)}]")
    for i, wire in fields:
        lines += _indent(wire.encode_source(f"v{i}", ns, str(i)))
    arguments = [str(x) for x in lead] + [f"v{i}" for i, _ in fields]
    lines.append(f"    return pack({', '.join(arguments)})")
    return _compile("encode", lines, ns)


def _decoder(
    layout: struct.Struct, fields: Sequence[tuple[int, Wire]], count: int, skip: int, why: str
) -> tuple[Callable[[bytes, str], tuple[Any, ...]], str]:
    """``def decode(payload, what)``: check the length, unpack (dropping ``skip`` leading
    items), convert each field ``v<i>``, return all ``count`` fields (None if not present)."""
    ns: dict[str, Any] = {"unpack": layout.unpack}
    present = {i for i, _ in fields}
    lines = [
        "def decode(payload, what):",
        f"    if len(payload) != {layout.size}:",
        "        raise JausDecodeError("
        f"f'{{what}}: payload is {{len(payload)}} bytes, {why} {layout.size}')",
    ]
    if layout.size:
        lines.append(f"    {'_, ' * skip}{_targets(f'v{i}' for i, _ in fields)}= unpack(payload)")
    for i, wire in fields:
        lines += _indent(wire.decode_source(f"v{i}", ns, str(i)))
    lines.append(
        f"    return ({_targets(f'v{i}' if i in present else 'None' for i in range(count))})"
    )
    return _compile("decode", lines, ns)


def _field_problem(
    fields: Sequence[tuple[str, Wire]], values: Sequence[Any], *, optional: bool
) -> str:
    for (name, wire), value in zip(fields, values, strict=False):
        if value is None and optional:
            continue
        try:
            wire.check(value)
        except JausEncodeError as exc:
            return f"{name}: {exc}"
        except TypeError:
            return f"{name}: wrong type {type(value).__name__}"
    return "a field does not fit its wire type"


class FixedLayout:
    """A payload of fixed fields, in record order.

    ``encode_values(values)`` is the generated encoder: fast, but it fails with whatever
    Python raises; :meth:`encode` (or :meth:`problem` after a failure) gives the
    JausEncodeError. ``decode(payload, what)`` is the generated decoder; it raises only
    JausDecodeError.
    """

    __slots__ = ("decode", "encode_values", "fields", "source", "struct")

    def __init__(self, fields: Sequence[tuple[str, Wire]]) -> None:
        self.fields = tuple(fields)
        self.struct = struct.Struct("<" + "".join(wire.fmt for _, wire in self.fields))
        indexed = list(enumerate(wire for _, wire in self.fields))
        self.encode_values, encode_source = _encoder("values", indexed, self.struct.pack)
        self.decode, decode_source = _decoder(self.struct, indexed, len(indexed), 0, "expected")
        self.source = f"{encode_source}\n\n{decode_source}"

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.fields)

    @property
    def size(self) -> int:
        return self.struct.size

    def problem(self, values: Sequence[Any]) -> str:
        """Why ``values`` do not encode, naming the field."""
        return _field_problem(self.fields, values, optional=False)

    def encode(self, values: Sequence[Any]) -> bytes:
        """Pack ``values`` (extra trailing values, such as a record's header, are ignored)."""
        try:
            return self.encode_values(values)
        except ENCODE_FAILURES:
            raise JausEncodeError(self.problem(values)) from None


class PresenceLayout:
    """A presence vector (``"B"`` or ``"H"``) then the present fields in bit order.

    Encoding computes the presence vector from the None-ness of the values, then calls an
    encoder generated for that presence vector; decoding reads the presence vector and calls
    the decoder generated for it. Both are generated on first use and cached (at most
    ``2 ** len(fields)`` of each).
    """

    __slots__ = (
        "_decoders",
        "_encoders",
        "encode_values",
        "fields",
        "pv_fmt",
        "pv_size",
        "source",
        "valid_bits",
    )

    def __init__(self, pv_fmt: str, fields: Sequence[tuple[str, Wire]]) -> None:
        self.pv_fmt = pv_fmt
        self.pv_size = struct.calcsize(pv_fmt)
        self.fields = tuple(fields)
        if len(self.fields) > 8 * self.pv_size:
            raise ValueError("more fields than presence-vector bits")
        self.valid_bits = (1 << len(self.fields)) - 1
        self._encoders: dict[int, Callable[..., bytes]] = {}
        self._decoders: dict[int, Callable[[bytes, str], tuple[Any, ...]]] = {}
        names = [f"v{i}" for i in range(len(self.fields))]
        pv = " | ".join(f"({name} is not None) << {i}" for i, name in enumerate(names))
        lines = [
            "def encode(values):",
            f"    {_targets(names)}= values[:{len(names)}]",
            f"    pv = {pv}",
            f"    return (encoders.get(pv) or encoder(pv))({', '.join(names)})",
        ]
        ns = {"encoders": self._encoders, "encoder": self._encoder}
        self.encode_values, self.source = _compile("encode", lines, ns)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.fields)

    def _present(self, pv: int) -> list[tuple[int, Wire]]:
        return [(i, wire) for i, (_, wire) in enumerate(self.fields) if pv >> i & 1]

    def _struct(self, pv: int) -> struct.Struct:
        return struct.Struct("<" + self.pv_fmt + "".join(wire.fmt for _, wire in self._present(pv)))

    def _encoder(self, pv: int) -> Callable[..., bytes]:
        signature = ", ".join(f"v{i}" for i in range(len(self.fields)))
        encoder, _ = _encoder(signature, self._present(pv), self._struct(pv).pack, pv)
        self._encoders[pv] = encoder
        return encoder

    def _decoder(self, pv: int) -> Callable[[bytes, str], tuple[Any, ...]]:
        why = f"presence vector 0x{pv:X} needs"
        decoder, _ = _decoder(self._struct(pv), self._present(pv), len(self.fields), 1, why)
        self._decoders[pv] = decoder
        return decoder

    def problem(self, values: Sequence[Any]) -> str:
        """Why ``values`` do not encode, naming the field."""
        return _field_problem(self.fields, values, optional=True)

    def encode(self, values: Sequence[Any]) -> bytes:
        """Pack the non-None ``values`` behind the presence vector they imply."""
        try:
            return self.encode_values(values)
        except ENCODE_FAILURES:
            raise JausEncodeError(self.problem(values)) from None

    def decode(self, payload: bytes, what: str) -> tuple[Any, ...]:
        """The field values, None where the presence vector leaves a field out.

        Presence-vector bits beyond the defined fields are masked off (not an error), so
        re-encoding the record writes the defined bits only.
        """
        if len(payload) < self.pv_size:
            raise JausDecodeError(f"{what}: payload of {len(payload)} bytes has no presence vector")
        # bits the message does not define are ignored, not refused: OpenJAUS sets all of
        # them (0xFFFF / 0xFF) by default and accepts such messages (shared/interop README)
        pv = (payload[0] if self.pv_size == 1 else payload[0] | payload[1] << 8) & self.valid_bits
        decoder = self._decoders.get(pv)
        if decoder is None:
            # compile only for payloads of the right length, so garbage does not fill the cache
            size = self._struct(pv).size
            if len(payload) != size:
                raise JausDecodeError(
                    f"{what}: payload is {len(payload)} bytes, presence vector 0x{pv:X} "
                    f"needs {size}"
                )
            decoder = self._decoder(pv)
        return decoder(payload, what)

"""``overdrive jaus``: decode and encode JAUS 3.3 messages and JUDP datagrams from the shell.

``decode HEX`` prints one JSON object per message, one per line (JSON Lines), for a single
message or every message of a datagram. ``encode NAME --field value ...`` prints the message
(or, with ``--judp``, a datagram holding it) as spaced upper-case hex, the notation of the
reference's byte vectors. Malformed input exits with status 2 and a one-line reason.
"""

from __future__ import annotations

import json
import types
import typing
from typing import Any, Final

import click
import msgspec

from overdrive.jaus.addresses import JausId
from overdrive.jaus.codec import (
    JausDecodeError,
    JausEncodeError,
    Message,
    decode,
    encode,
    message_types,
    to_dict,
)
from overdrive.jaus.judp import TRANSPORT_VERSION, decode_datagram, encode_datagram
from overdrive.jaus.messages import (
    Horn,
    JausTimestamp,
    Lights,
    ReportErrorCount,
    SetMotionProfile,
    SetWrenchEffort,
)

# --------------------------------------------------------------------------- helpers


def _fail(reason: str) -> typing.NoReturn:
    click.echo(f"error: {reason}", err=True)
    raise click.exceptions.Exit(2)


def _parse_hex(parts: tuple[str, ...]) -> bytes:
    text = "".join("".join(parts).split())
    if text[:2].lower() == "0x":
        text = text[2:]
    if not text:
        _fail("no hex given")
    try:
        return bytes.fromhex(text)
    except ValueError:
        _fail(f"not hexadecimal: {text[:40]!r}{'...' if len(text) > 40 else ''}")


def _looks_like_datagram(data: bytes) -> bool:
    """A JUDP datagram starts 01 00 00; a JAUS 3.3 message has version 2 in its byte 1."""
    return len(data) >= 5 and data[0] == TRANSPORT_VERSION and data[1] == 0 and data[2] == 0


def decode_any(data: bytes, kind: str = "auto") -> list[Message]:
    """Decode ``data`` as a message, a datagram, or (``auto``) whichever it is."""
    if kind == "message":
        return [decode(data)]
    if kind == "datagram" or _looks_like_datagram(data):
        try:
            return decode_datagram(data)
        except JausDecodeError:
            if kind == "datagram":
                raise
            try:
                return [decode(data)]
            except JausDecodeError:
                pass
            raise
    return [decode(data)]


class _IntParam(click.ParamType):
    """An integer in decimal or with a 0x/0b/0o prefix (command codes read better in hex)."""

    name = "integer"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, int):
            return value
        try:
            return int(str(value), 0)
        except ValueError:
            self.fail(f"{value!r} is not an integer", param, ctx)


class _JausIdParam(click.ParamType):
    name = "s.n.c.i"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> JausId:
        if isinstance(value, JausId):
            return value
        try:
            return JausId.parse(str(value))
        except ValueError as exc:
            self.fail(str(exc), param, ctx)


class _TimestampParam(click.ParamType):
    name = "day:hour:minute:second.millisecond"

    def convert(
        self, value: Any, param: click.Parameter | None, ctx: click.Context | None
    ) -> JausTimestamp:
        if isinstance(value, JausTimestamp):
            return value
        try:
            day, hour, minute, rest = str(value).split(":")
            second, _, millis = rest.partition(".")
            return JausTimestamp(int(day), int(hour), int(minute), int(second), int(millis or 0))
        except ValueError:
            self.fail(f"{value!r} is not day:hour:minute:second.millisecond", param, ctx)


INT: Final = _IntParam()
JAUS_ID: Final = _JausIdParam()
TIMESTAMP: Final = _TimestampParam()

# --------------------------------------------------------------------------- commands


@click.group(name="jaus")
def jaus() -> None:
    """JAUS 3.3 / JUDP tools: decode and encode XGV messages."""


@jaus.command(name="decode")
@click.argument("hex_text", nargs=-1, required=True, metavar="HEX")
@click.option(
    "--as",
    "kind",
    type=click.Choice(["auto", "message", "datagram"]),
    default="auto",
    show_default=True,
    help="Read HEX as one JAUS message, a JUDP datagram, or guess.",
)
def decode_command(hex_text: tuple[str, ...], kind: str) -> None:
    """Decode HEX (spaces allowed) and print one JSON object per message, one per line."""
    data = _parse_hex(hex_text)
    try:
        messages = decode_any(data, kind)
    except JausDecodeError as exc:
        _fail(str(exc))
    for message in messages:
        click.echo(json.dumps(to_dict(message)))


@jaus.group(name="encode")
def encode_group() -> None:
    """Encode one message: ``encode NAME --field value ...``; prints hex."""


def _header_options(default: Any) -> list[click.Option]:
    return [
        click.Option(["--src"], type=JAUS_ID, default=str(default.source), show_default=True,
                     help="Source JAUS ID."),
        click.Option(["--dst"], type=JAUS_ID, default=str(default.destination),
                     show_default=True, help="Destination JAUS ID."),
        click.Option(["--seq"], type=click.IntRange(0, 0xFFFF), default=0, show_default=True,
                     help="Sequence number."),
        click.Option(["--priority"], type=click.IntRange(0, 15), default=default.priority,
                     show_default=True),
        click.Option(["--ack-nak"], type=click.IntRange(0, 3), default=default.ack_nak,
                     show_default=True, help="0 none, 1 request, 2 NAK, 3 ACK."),
        click.Option(["--service-connection/--no-service-connection"],
                     default=default.service_connection, show_default=True),
        click.Option(["--judp"], is_flag=True, help="Wrap the message in a JUDP datagram."),
    ]  # fmt: skip


_HEADER_KEYS: Final = ("src", "dst", "seq", "priority", "ack_nak", "service_connection", "judp")


def _option_for(name: str, annotation: Any, required: bool) -> click.Option | None:
    """A ``--field-name`` option for a simple field, None for the ones built by hand."""
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    base = (
        args[0] if typing.get_origin(annotation) in (typing.Union, types.UnionType) else annotation
    )
    param_type: Any = {float: float, int: INT, bool: bool, JausId: JAUS_ID,
                       JausTimestamp: TIMESTAMP}.get(base)  # fmt: skip
    if param_type is None:
        return None
    return click.Option(
        ["--" + name.replace("_", "-")], type=param_type, required=required, default=None
    )


def _encode_command(cls: type[Message]) -> click.Command:
    fields = [f for f in msgspec.structs.fields(cls) if f.name != "header"]
    params: list[click.Parameter] = []
    simple: list[str] = []
    for field in fields:
        option = _option_for(field.name, field.type, field.required)
        if option is not None:
            params.append(option)
            simple.append(field.name)
    params += _EXTRA_OPTIONS.get(cls, [])
    default_header = cls.__struct_defaults__[-1]  # header is every record's last field

    def callback(**kwargs: Any) -> None:
        header = default_header.replace(
            source=kwargs["src"],
            destination=kwargs["dst"],
            sequence=kwargs["seq"],
            priority=kwargs["priority"],
            ack_nak=kwargs["ack_nak"],
            service_connection=kwargs["service_connection"],
        )
        values = {k: kwargs[k] for k in simple if kwargs[k] is not None}
        extra = {k: v for k, v in kwargs.items() if k not in values and k not in _HEADER_KEYS}
        try:
            message = _BUILDERS.get(cls, _build_plain)(cls, values, extra, header)
            wire = encode_datagram(message) if kwargs["judp"] else encode(message)
        except (JausEncodeError, TypeError, ValueError) as exc:
            _fail(str(exc))
        click.echo(wire.hex(" ").upper())

    doc = (cls.__doc__ or cls.name).strip().splitlines()[0].replace("``", "")
    return click.Command(
        cls.name, params=params + _header_options(default_header), callback=callback, help=doc
    )


def _build_plain(
    cls: type[Message], values: dict[str, Any], extra: dict[str, Any], header: Any
) -> Message:
    return cls(**values, header=header)


def _build_wrench(
    cls: type[Message], values: dict[str, Any], extra: dict[str, Any], header: Any
) -> Message:
    for alias, field in (
        ("throttle_pct", "propulsive_linear_x_pct"),
        ("steering_pct", "propulsive_rotational_z_pct"),
        ("brake_pct", "resistive_linear_x_pct"),
    ):
        if extra.get(alias) is not None:
            values[field] = extra[alias]
    return cls(**values, header=header)


def _build_motion_profile(
    cls: type[Message], values: dict[str, Any], extra: dict[str, Any], header: Any
) -> Message:
    message = SetMotionProfile.single(
        extra["speed_mps"],
        extra["max_accel_mps2"],
        extra["curvature_1pm"],
        extra["curvature_rate_1pms"],
        extra["duration_s"],
        header=header,
    )
    return msgspec.structs.replace(message, **values)


def _build_signals(
    cls: type[Message], values: dict[str, Any], extra: dict[str, Any], header: Any
) -> Message:
    for group, kind in (("horn", Horn), ("lights", Lights)):
        first = "status" if group == "horn" else "state"
        parts = [extra.get(f"{group}_{p}") for p in (first, "period_on_raw", "period_off_raw")]
        if any(p is not None for p in parts):
            values[group] = kind(*(p or 0 for p in parts))
    return cls(**values, header=header)


def _build_error_count(
    cls: type[Message], values: dict[str, Any], extra: dict[str, Any], header: Any
) -> Message:
    return cls(**values, counts=tuple(extra["count"]), header=header)


def _signals_options() -> list[click.Parameter]:
    return [
        click.Option([f"--{group}-{part}"], type=INT, default=None)
        for group, first in (("horn", "status"), ("lights", "state"))
        for part in (first, "period-on-raw", "period-off-raw")
    ]


_EXTRA_OPTIONS: Final[dict[type[Message], list[click.Parameter]]] = {
    SetWrenchEffort: [
        click.Option(["--throttle-pct"], type=float, help="XGV throttle (propulsive linear X)."),
        click.Option(["--steering-pct"], type=float, help="XGV steering (propulsive rotational Z)."),
        click.Option(["--brake-pct"], type=float, help="XGV brake (resistive linear X)."),
    ],
    SetMotionProfile: [
        click.Option(["--speed-mps"], type=float, required=True),
        click.Option(["--max-accel-mps2"], type=float, required=True),
        click.Option(["--curvature-1pm"], type=float, default=0.0, show_default=True),
        click.Option(["--curvature-rate-1pms"], type=float, default=0.0, show_default=True),
        click.Option(["--duration-s"], type=float, default=0.4, show_default=True),
    ],
    ReportErrorCount: [click.Option(["--count"], type=INT, multiple=True, help="Repeatable.")],
}  # fmt: skip
_BUILDERS: Final = {
    SetWrenchEffort: _build_wrench,
    SetMotionProfile: _build_motion_profile,
    ReportErrorCount: _build_error_count,
}
for _cls in message_types():
    if _cls.name in ("set-signals", "report-signals"):
        _EXTRA_OPTIONS[_cls] = _signals_options()
        _BUILDERS[_cls] = _build_signals
    encode_group.add_command(_encode_command(_cls))

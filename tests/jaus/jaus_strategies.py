"""Hypothesis strategies for every JAUS record, over each field's full range (and beyond it
for scaled fields, to exercise clamping)."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from overdrive.jaus import (
    ConfigurationNode,
    Header,
    Horn,
    JausId,
    JausTimestamp,
    Lights,
    Message,
    Motion,
    ReportComponentControl,
    ReportConfiguration,
    ReportErrorCount,
    ReportIdentification,
    ReportServices,
    ReportSignals,
    Service,
    SetMotionProfile,
    SetSignals,
    UnknownMessage,
    message_type,
    message_types,
)
from overdrive.jaus.layout import FixedLayout, PresenceLayout, ScaledWire, Wire
from overdrive.jaus.messages import MILLIS_U16, MOTION_LAYOUT, TIMESTAMP

INT_BOUNDS = {"B": (0, 0xFF), "H": (0, 0xFFFF), "I": (0, 0xFFFFFFFF), "i": (-(2**31), 2**31 - 1)}

ids = st.builds(JausId, *(st.integers(0, 255) for _ in range(4)))
headers = st.builds(
    Header,
    destination=ids,
    source=ids,
    priority=st.integers(0, 15),
    ack_nak=st.integers(0, 3),
    service_connection=st.booleans(),
    version=st.integers(0, 63),
    sequence=st.integers(0, 0xFFFF),
)
timestamps = st.builds(
    JausTimestamp,
    day=st.integers(0, 31),
    hour=st.integers(0, 31),
    minute=st.integers(0, 63),
    second=st.integers(0, 63),
    millisecond=st.integers(0, 1023),
)
u8 = st.integers(0, 0xFF)
curvatures = st.one_of(
    st.floats(-2.0, 2.0), st.floats(-1e6, 1e6), st.sampled_from([0.0, 1e300, -1e300])
)
durations = st.floats(0.0, 65.535)


def scaled_values(wire: ScaledWire) -> st.SearchStrategy[float]:
    """Values across the range, a margin outside it, and the ends themselves."""
    lo, hi = wire.scaled.lo, wire.scaled.hi
    span = hi - lo
    return st.one_of(
        st.floats(lo, hi),
        st.floats(lo - span, hi + span),
        st.sampled_from([lo, hi, (lo + hi) / 2, 0.0 if lo <= 0 <= hi else lo]),
    )


def wire_values(wire: Wire) -> st.SearchStrategy[Any]:
    if isinstance(wire, ScaledWire):
        return scaled_values(wire)
    if wire is TIMESTAMP:
        return timestamps
    if wire is MILLIS_U16:
        return durations
    if wire.to_raw is not None:  # atan-scaled curvature
        return curvatures
    return st.integers(*INT_BOUNDS[wire.fmt])


def layout_message(cls: type[Message]) -> st.SearchStrategy[Message]:
    layout = cls.layout  # type: ignore[attr-defined]
    if isinstance(layout, PresenceLayout):
        fields = {name: st.none() | wire_values(wire) for name, wire in layout.fields}
    else:
        assert isinstance(layout, FixedLayout)
        fields = {name: wire_values(wire) for name, wire in layout.fields}
    return st.builds(cls, header=headers, **fields)


motions = st.builds(Motion, **{name: wire_values(wire) for name, wire in MOTION_LAYOUT.fields})


def signals(cls: type[Message]) -> st.SearchStrategy[Message]:
    return st.builds(
        cls,
        version=u8,
        turn_signal=st.none() | u8,
        horn=st.none() | st.builds(Horn, u8, u8, u8),
        lights=st.none() | st.builds(Lights, u8, u8, u8),
        header=headers,
    )


CUSTOM: dict[type[Message], st.SearchStrategy[Message]] = {
    SetMotionProfile: st.builds(
        SetMotionProfile,
        motions=st.lists(motions, max_size=6).map(tuple),
        version=u8,
        header=headers,
    ),
    SetSignals: signals(SetSignals),
    ReportSignals: signals(ReportSignals),
    ReportErrorCount: st.builds(
        ReportErrorCount,
        version=u8,
        reserved=u8,
        counts=st.lists(st.integers(-(2**31), 2**31 - 1), max_size=20).map(tuple),
        header=headers,
    ),
    ReportComponentControl: st.builds(
        ReportComponentControl, controller=ids, authority=u8, header=headers
    ),
    ReportIdentification: st.builds(
        ReportIdentification, query_type=u8, authority=u8, type=st.integers(0, 0xFFFF),
        identification=st.text(st.characters(min_codepoint=1, max_codepoint=255), max_size=79),
        header=headers,
    ),
    ReportConfiguration: st.builds(
        ReportConfiguration,
        nodes=st.lists(st.builds(ConfigurationNode, u8, st.lists(st.tuples(u8, u8),
                                                                 max_size=6).map(tuple)),
                       max_size=4).map(tuple),
        header=headers,
    ),
    ReportServices: st.builds(
        ReportServices,
        services=st.lists(st.builds(Service, st.integers(0, 0xFFFF), *(
            st.lists(st.tuples(st.integers(0, 0xFFFF), st.integers(0, 0xFFFFFFFF)),
                     max_size=5).map(tuple) for _ in range(2))), max_size=4).map(tuple),
        header=headers,
    ),
}


@st.composite
def unknown_messages(draw: Any) -> UnknownMessage:
    code, experimental = draw(
        st.tuples(st.integers(0, 0xFFFF), st.booleans()).filter(
            lambda key: message_type(key[0], key[1]) is None
        )
    )
    return UnknownMessage(code, draw(st.binary(max_size=64)), experimental, draw(headers))


def message_strategy(cls: type[Message]) -> st.SearchStrategy[Message]:
    if cls is UnknownMessage:
        return unknown_messages()
    if cls in CUSTOM:
        return CUSTOM[cls]
    return layout_message(cls)


ALL_TYPES: tuple[type[Message], ...] = (*message_types(), UnknownMessage)
any_message = st.one_of([message_strategy(cls) for cls in ALL_TYPES])

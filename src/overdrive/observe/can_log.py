"""CAN logs: a run's raw CAN frames out of ``run.mcap`` as candump or ASC files, and any CAN log
read back through the PACMod 3 decoder.

A run that drove a CAN kit records every frame its CAN edge sent and received on the
``can/frames`` channel (``CanTraffic``: time, id, data, direction). ``export_can_log`` writes
them with python-can's own writers (``CanutilsLogWriter``: ``candump -L`` lines ending ``T`` or
``R``; ``ASCWriter``: Vector ASC with ``Tx`` / ``Rx``), so candump, SavvyCAN, CANalyzer and
python-can read them; the direction is kept. ``replay_can_log`` reads a candump, ASC or BLF
file with python-can's readers (``can.LogReader``) and decodes each frame with
``Pacmod3Codec``: a frame the codec does not read is counted as unknown, a frame it refuses
(wrong length, bad complement, out of range, error or remote frame, CAN FD) as malformed, and
neither stops the replay. A file python-can cannot parse past some line ends the replay there
with that line's error kept (``CanReplay.error``).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final, Literal

import msgspec
from mcap.reader import make_reader

import can
from overdrive.kits.frames import CanFrame, KitDecodeError, KitError, UnknownFrame
from overdrive.kits.pacmod3 import Command, Dialect, Pacmod3Codec, Report
from overdrive.messages import CanFrameRecord, CanTraffic, Topic

CanLogFormat = Literal["candump", "asc"]
SUFFIXES: Final[dict[str, str]] = {"candump": ".log", "asc": ".asc"}
"""The file suffix python-can's ``can.Logger`` / ``can.LogReader`` associate with each format."""
DEFAULT_CHANNEL: Final = "can0"
"""candump's channel name when a recording names none."""


class CanLogError(ValueError):
    """A run or CAN log that cannot be exported or replayed (no frames, unreadable file)."""


def run_mcap_path(run: str | Path) -> Path:
    """``run`` itself when it is a file, else ``run/run.mcap``."""
    path = Path(run)
    return path / "run.mcap" if path.is_dir() else path


def read_can_traffic(run: str | Path) -> Iterator[tuple[str, CanFrameRecord]]:
    """Every frame on the ``can/frames`` channel of a run's ``run.mcap``, as
    ``(channel, record)`` in recorded order."""
    path = run_mcap_path(run)
    if not path.is_file():
        raise CanLogError(f"{path}: no such file")
    decoder = msgspec.json.Decoder(CanTraffic)
    with path.open("rb") as stream:
        try:
            reader = make_reader(stream)
            for _schema, _channel, message in reader.iter_messages(topics=[Topic.CAN_FRAMES]):
                try:
                    traffic = decoder.decode(message.data)
                except msgspec.DecodeError as e:
                    raise CanLogError(f"{path}: a {Topic.CAN_FRAMES} message is not "
                                      f"CanTraffic: {e}") from e
                for record in traffic.frames:
                    yield traffic.channel, record
        except CanLogError:
            raise
        except Exception as e:   # the mcap reader's own errors on a corrupt or foreign file
            raise CanLogError(f"{path}: not a readable run.mcap ({type(e).__name__}: {e})") from e


def to_can_message(channel: str, record: CanFrameRecord) -> can.Message:
    """A recorded frame as python-can's ``Message``; ``is_rx`` false for a frame the stack
    sent."""
    return can.Message(timestamp=record.time_s, arbitration_id=record.arbitration_id,
                       is_extended_id=record.is_extended, data=record.data,
                       dlc=len(record.data), is_rx=record.direction == "rx",
                       channel=channel or DEFAULT_CHANNEL)


def export_can_log(run: str | Path, out: str | Path, fmt: CanLogFormat) -> int:
    """Write the run's CAN frames to ``out`` as ``fmt`` (time order, direction kept); returns
    how many. Raises ``CanLogError`` when the run recorded none (nothing is written)."""
    if fmt not in SUFFIXES:
        raise CanLogError(f"CAN log format {fmt!r}: expected one of {', '.join(SUFFIXES)}")
    frames = sorted(read_can_traffic(run), key=lambda item: item[1].time_s)   # stable
    if not frames:
        raise CanLogError(f"{run_mcap_path(run)}: no CAN frames recorded "
                          f"(no {Topic.CAN_FRAMES} channel)")
    writer_cls = can.CanutilsLogWriter if fmt == "candump" else can.ASCWriter
    try:
        with writer_cls(str(out)) as writer:
            for channel, record in frames:
                writer.on_message_received(to_can_message(channel, record))
    except OSError as e:
        raise CanLogError(f"{out}: cannot write: {e.strerror or e}") from e
    return len(frames)


FrameKind = Literal["decoded", "unknown", "malformed"]


@dataclass(frozen=True)
class ReplayedFrame:
    """One frame of a CAN log and what the decoder made of it."""

    time_s: float
    direction: Literal["rx", "tx"]
    frame: CanFrame | None          # None: not a classic data frame
    kind: FrameKind
    message: Command | Report | None = None
    error: str = ""

    def format(self) -> str:
        """One line: time, direction, ``ID#DATA``, then the message or why it is not one."""
        raw = str(self.frame) if self.frame is not None else "-"
        what = repr(self.message) if self.kind == "decoded" else f"{self.kind}: {self.error}"
        return f"{self.time_s:14.6f} {self.direction} {raw:<24} {what}"


@dataclass
class CanReplay:
    """Counts of a replay; ``error`` set when the file stopped being readable."""

    counts: dict[FrameKind, int] = field(
        default_factory=lambda: {"decoded": 0, "unknown": 0, "malformed": 0})
    error: str = ""

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def format(self) -> str:
        c = self.counts
        line = (f"{self.total} frames: {c['decoded']} decoded, {c['unknown']} unknown, "
                f"{c['malformed']} malformed")
        return f"{line}; stopped: {self.error}" if self.error else line


def classify(msg: can.Message, codec: Pacmod3Codec) -> ReplayedFrame:
    """What the decoder makes of one python-can message; never raises."""
    direction: Literal["rx", "tx"] = "rx" if msg.is_rx else "tx"
    time_s = float(msg.timestamp)
    kinds = [name for name, flag in (("error frame", msg.is_error_frame),
                                     ("remote frame", msg.is_remote_frame),
                                     ("CAN FD frame", msg.is_fd)) if flag]
    if kinds:
        return ReplayedFrame(time_s, direction, None, "malformed", error=kinds[0])
    try:
        frame = CanFrame(arbitration_id=msg.arbitration_id, data=bytes(msg.data),
                         is_extended=msg.is_extended_id)
    except KitDecodeError as e:
        return ReplayedFrame(time_s, direction, None, "malformed", error=str(e))
    try:
        return ReplayedFrame(time_s, direction, frame, "decoded", codec.decode(frame))
    except UnknownFrame as e:
        return ReplayedFrame(time_s, direction, frame, "unknown", error=str(e))
    except KitDecodeError as e:
        return ReplayedFrame(time_s, direction, frame, "malformed", error=str(e))


def make_codec(dialect: str, dbc: str | Path | None = None) -> Pacmod3Codec:
    """The PACMod 3 codec a replay decodes with; ``CanLogError`` for a bad dialect or DBC."""
    if dialect not in ("v3", "v14"):
        raise CanLogError(f"PACMod 3 dialect {dialect!r}: expected 'v3' or 'v14'")
    chosen: Dialect = "v3" if dialect == "v3" else "v14"
    try:
        return Pacmod3Codec(chosen, dbc_path=dbc)
    except KitError as e:
        raise CanLogError(str(e)) from e


def replay_can_log(path: str | Path, codec: Pacmod3Codec,
                   summary: CanReplay | None = None) -> Iterator[ReplayedFrame]:
    """Each frame of the CAN log ``path`` (candump ``.log``, ``.asc``, ``.blf``) decoded by
    ``codec``, counted in ``summary``. An unreadable line ends the iteration with
    ``summary.error`` set; an unknown suffix raises ``CanLogError`` before any frame."""
    summary = summary if summary is not None else CanReplay()
    path = Path(path)
    if not path.is_file():
        raise CanLogError(f"{path}: no such file")
    try:
        reader = can.LogReader(str(path))
    except Exception as e:   # python-can's readers raise their parsers' own (BLFParseError)
        raise CanLogError(f"{path}: {type(e).__name__}: {e}") from e
    with reader:
        messages = iter(reader)
        while True:
            try:
                msg = next(messages)
            except StopIteration:
                return
            except Exception as e:   # python-can's readers raise what their parsers raise
                summary.error = f"{path}: unreadable after {summary.total} frames " \
                                f"({type(e).__name__}: {e})"
                return
            replayed = classify(msg, codec)
            summary.counts[replayed.kind] += 1
            yield replayed


__all__ = ["SUFFIXES", "CanLogError", "CanLogFormat", "CanReplay", "ReplayedFrame", "classify",
           "export_can_log", "make_codec", "read_can_traffic", "replay_can_log", "run_mcap_path",
           "to_can_message"]

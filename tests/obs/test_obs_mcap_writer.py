"""overdrive.observe.mcap_writer: files the ``mcap`` package reads back whole, with every index and CRC."""

from __future__ import annotations

import io
import struct
import zlib

import pytest
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

from overdrive.observe.mcap_writer import MAGIC, McapWriter

OP_FOOTER, OP_CHUNK, OP_MESSAGE_INDEX, OP_CHUNK_INDEX = 0x02, 0x06, 0x07, 0x08
OP_ATTACHMENT, OP_SUMMARY_OFFSET, OP_DATA_END = 0x09, 0x0E, 0x0F


def _records(data: bytes, start: int, end: int) -> list[tuple[int, int, bytes]]:
    """``(offset, opcode, content)`` of the records in ``data[start:end]``."""
    out = []
    pos = start
    while pos < end:
        opcode, length = struct.unpack_from("<BQ", data, pos)
        out.append((pos, opcode, data[pos + 9:pos + 9 + length]))
        pos += 9 + length
    assert pos == end
    return out


def _write(chunk_size: int, messages: list[tuple[int, int, bytes]]) -> bytes:
    buf = io.BytesIO()
    writer = McapWriter(buf, chunk_size=chunk_size)
    writer.start(profile="", library="test")
    writer.add_attachment(5, 6, "a.txt", "text/plain", b"attached")
    writer.add_metadata("meta", {"k": "v", "empty": ""})
    schema = writer.register_schema("S", "jsonschema", b'{"type": "object"}')
    channels = [writer.register_channel(f"t{i}", "json", schema, {"origin": "bus"})
                for i in range(3)]
    for channel, t, payload in messages:
        writer.add_message(channels[channel], t, payload, t, sequence=t)
    writer.finish()
    return buf.getvalue()


MESSAGES = [(i % 3, 1_000 * i - (1_500 if i % 7 == 3 else 0), b'{"i":%d}' % i)
            for i in range(500)]   # some out of time order


@pytest.mark.parametrize("chunk_size", [64, 4096, 1 << 20])
def test_the_mcap_reader_reads_everything_back(chunk_size: int) -> None:
    data = _write(chunk_size, MESSAGES)
    reader = make_reader(io.BytesIO(data), validate_crcs=True)
    got = [(c.topic, m.log_time, m.publish_time, m.sequence, bytes(m.data))
           for _s, c, m in reader.iter_messages(log_time_order=False)]
    assert got == [(f"t{c}", t, t, t, p) for c, t, p in MESSAGES]
    in_time_order = [m.log_time for _s, _c, m in reader.iter_messages()]
    assert in_time_order == sorted(t for _c, t, _p in MESSAGES)
    summary = reader.get_summary()
    assert summary is not None and summary.statistics is not None
    stats = summary.statistics
    assert stats.message_count == len(MESSAGES)
    times = [t for _c, t, _p in MESSAGES]
    assert (stats.message_start_time, stats.message_end_time) == (min(times), max(times))
    assert stats.channel_message_counts == {1: 167, 2: 167, 3: 166}
    assert stats.chunk_count == len(summary.chunk_indexes) >= (2 if chunk_size < 4096 else 1)
    assert (stats.schema_count, stats.channel_count) == (1, 3)
    assert (stats.attachment_count, stats.metadata_count) == (1, 1)
    [attachment] = list(reader.iter_attachments())
    assert (attachment.name, bytes(attachment.data), attachment.create_time,
            attachment.log_time) == ("a.txt", b"attached", 5, 6)
    [metadata] = list(reader.iter_metadata())
    assert metadata.name == "meta" and metadata.metadata == {"k": "v", "empty": ""}
    # the streaming reader checks the chunk CRCs and the data section CRC
    records = list(StreamReader(io.BytesIO(data), validate_crcs=True).records)
    assert sum(type(r).__name__ == "Message" for r in records) == len(MESSAGES)


def test_indexes_offsets_and_crcs_are_right() -> None:
    data = _write(256, MESSAGES)
    assert data[:8] == MAGIC and data[-8:] == MAGIC
    footer_at = len(data) - 8 - 9 - 20
    opcode, length, summary_start, summary_offset_start, summary_crc = struct.unpack_from(
        "<BQQQI", data, footer_at)
    assert (opcode, length) == (OP_FOOTER, 20)
    assert summary_crc == zlib.crc32(data[summary_start:footer_at + 9 + 16])
    body = _records(data, 8, summary_start)
    assert body[-1][1] == OP_DATA_END
    [data_crc] = struct.unpack("<I", body[-1][2])
    assert data_crc == zlib.crc32(data[:body[-1][0]])
    by_offset = {offset: (op, content) for offset, op, content in body}
    for _offset, op, content in body:
        if op == OP_ATTACHMENT:
            assert struct.unpack("<I", content[-4:])[0] == zlib.crc32(content[:-4])
    summary = _records(data, summary_start, footer_at)
    groups = [struct.unpack("<BQQ", c) for _o, op, c in summary if op == OP_SUMMARY_OFFSET]
    assert summary_offset_start == min(o for o, op, _c in summary if op == OP_SUMMARY_OFFSET)
    for group_opcode, start, length in groups:
        inside = _records(data, start, start + length)
        assert inside and all(op == group_opcode for _o, op, _c in inside)
    chunk_indexes = [c for _o, op, c in summary if op == OP_CHUNK_INDEX]
    assert len(chunk_indexes) > 3
    for content in chunk_indexes:
        _t0, _t1, chunk_offset, chunk_length, map_length = struct.unpack_from("<QQQQI", content)
        assert by_offset[chunk_offset][0] == OP_CHUNK
        assert chunk_length == 9 + len(by_offset[chunk_offset][1])
        entries = content[36:36 + map_length]
        for i in range(0, len(entries), 10):
            channel_id, index_offset = struct.unpack_from("<HQ", entries, i)
            op, index = by_offset[index_offset]
            assert op == OP_MESSAGE_INDEX and struct.unpack_from("<H", index)[0] == channel_id


def test_same_content_as_the_mcap_package_writer() -> None:
    ours = _write(4096, MESSAGES)
    buf = io.BytesIO()
    writer = Writer(buf, chunk_size=4096)
    writer.start(profile="", library="test")
    writer.add_attachment(5, 6, "a.txt", "text/plain", b"attached")
    writer.add_metadata("meta", {"k": "v", "empty": ""})
    schema = writer.register_schema("S", "jsonschema", b'{"type": "object"}')
    channels = [writer.register_channel(f"t{i}", "json", schema, {"origin": "bus"})
                for i in range(3)]
    for channel, t, payload in MESSAGES:
        writer.add_message(channels[channel], t, payload, t, sequence=t)
    writer.finish()

    def content(data: bytes) -> tuple:
        reader = make_reader(io.BytesIO(data))
        summary = reader.get_summary()
        assert summary is not None
        return ([(s.name, s.encoding, bytes(s.data), c.topic, c.message_encoding, c.metadata,
                  m.log_time, m.publish_time, m.sequence, bytes(m.data))
                 for s, c, m in reader.iter_messages(log_time_order=False)],
                summary.statistics, [(a.name, bytes(a.data)) for a in reader.iter_attachments()],
                [(m.name, m.metadata) for m in reader.iter_metadata()])

    assert content(ours) == content(buf.getvalue())


def test_no_messages_is_still_a_valid_file() -> None:
    buf = io.BytesIO()
    writer = McapWriter(buf)
    writer.start()
    writer.register_schema("S", "jsonschema", b"{}")
    writer.finish()
    reader = make_reader(io.BytesIO(buf.getvalue()), validate_crcs=True)
    assert list(reader.iter_messages()) == []
    summary = reader.get_summary()
    assert summary is not None and summary.statistics.message_count == 0
    assert [s.name for s in summary.schemas.values()] == ["S"]

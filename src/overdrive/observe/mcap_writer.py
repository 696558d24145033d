"""A small MCAP writer for the recorder's hot path (MCAP format version 0, https://mcap.dev/spec).

The ``mcap`` package's ``Writer`` builds a dataclass per message and writes each field through
a ``BytesIO``: ~10-40 us per message, which made ``run.mcap`` cost more than the simulation it
records. This writer appends each message record to the open chunk's ``bytearray`` with one
``struct`` call and keeps the message index as flat integer lists, so a message costs about a
microsecond plus its JSON encoding. The file layout is what the ``mcap`` package writes (and
reads back, which the tests do):

    magic, Header, [Attachment | Metadata | Chunk + its Message Indexes]..., Data End,
    summary: Schemas, Channels, Statistics, Chunk Indexes, Attachment Indexes,
             Metadata Indexes, Summary Offsets; Footer, magic

Chunks are zstd-compressed and carry the schema and channel records before their first
message; every CRC the format defines is filled in (chunk, attachment, data section, summary).
"""

from __future__ import annotations

import struct
import zlib
from typing import IO

import zstandard

MAGIC = b"\x89MCAP0\r\n"

OP_HEADER = 0x01
OP_FOOTER = 0x02
OP_SCHEMA = 0x03
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
OP_CHUNK = 0x06
OP_MESSAGE_INDEX = 0x07
OP_CHUNK_INDEX = 0x08
OP_ATTACHMENT = 0x09
OP_ATTACHMENT_INDEX = 0x0A
OP_STATISTICS = 0x0B
OP_METADATA = 0x0C
OP_METADATA_INDEX = 0x0D
OP_SUMMARY_OFFSET = 0x0E
OP_DATA_END = 0x0F

# Message record: opcode u8, record length u64, channel_id u16, sequence u32, log_time u64,
# publish_time u64, then the message data (the rest of the record).
MESSAGE_HEADER = struct.Struct("<BQHIQQ")
MESSAGE_FIXED_LENGTH = MESSAGE_HEADER.size - 9   # record length = this + len(data)
ZSTD_LEVEL = 1   # fastest; on our JSON chunks also smaller than level 3 (measured on the demo)


def _u8(v: int) -> bytes:
    return struct.pack("<B", v)


def _u16(v: int) -> bytes:
    return struct.pack("<H", v)


def _u32(v: int) -> bytes:
    return struct.pack("<I", v)


def _u64(v: int) -> bytes:
    return struct.pack("<Q", v)


def _string(s: str) -> bytes:
    data = s.encode()
    return _u32(len(data)) + data


def _bytes32(data: bytes) -> bytes:
    return _u32(len(data)) + data


def _string_map(mapping: dict[str, str]) -> bytes:
    body = b"".join(_string(k) + _string(v) for k, v in mapping.items())
    return _u32(len(body)) + body


def _record(opcode: int, content: bytes) -> bytes:
    return struct.pack("<BQ", opcode, len(content)) + content


class McapWriter:
    """Writes an MCAP file to a binary stream (left open): chunked, zstd, fully indexed.

    Same calls as ``mcap.writer.Writer`` for what the recorder uses: ``start``,
    ``register_schema``, ``register_channel``, ``add_message``, ``add_attachment``,
    ``add_metadata``, ``finish``. Message log times need not be ordered; each chunk records
    its own time range.
    """

    def __init__(self, stream: IO[bytes], *, chunk_size: int = 1 << 20,
                 zstd_level: int = ZSTD_LEVEL) -> None:
        self._stream = stream
        self._offset = 0               # bytes written to the stream so far
        self._data_crc = 0             # CRC of the data section, magic included
        self.chunk_size = chunk_size
        self._compressor = zstandard.ZstdCompressor(level=zstd_level)
        self._schemas: list[bytes] = []        # Schema records, for the summary
        self._channels: list[bytes] = []       # Channel records, for the summary
        self._pending: list[bytes] = []        # schema/channel records the next chunk must carry
        self._chunk = bytearray()
        self._chunk_start_ns = 0
        self._chunk_end_ns = 0
        self._index: dict[int, list[int]] = {}  # channel id -> [log_time, offset, ...] in the chunk
        self._chunk_indexes: list[bytes] = []
        self._attachment_indexes: list[bytes] = []
        self._metadata_indexes: list[bytes] = []
        self._channel_counts: dict[int, int] = {}
        self._message_count = 0
        self._start_ns = 0
        self._end_ns = 0
        self._attachment_count = 0
        self._metadata_count = 0
        self._finished = False

    # ------------------------------------------------------------------ output

    def _write(self, data: bytes | bytearray, data_section: bool = True) -> None:
        self._stream.write(data)
        self._offset += len(data)
        if data_section:
            self._data_crc = zlib.crc32(data, self._data_crc)

    def start(self, profile: str = "", library: str = "") -> None:
        self._write(MAGIC)
        self._write(_record(OP_HEADER, _string(profile) + _string(library)))

    # ------------------------------------------------------------------ definitions

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema_id = len(self._schemas) + 1
        record = _record(OP_SCHEMA, _u16(schema_id) + _string(name) + _string(encoding)
                         + _bytes32(data))
        self._schemas.append(record)
        self._pending.append(record)
        return schema_id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str] | None = None) -> int:
        channel_id = len(self._channels) + 1
        record = _record(OP_CHANNEL, _u16(channel_id) + _u16(schema_id) + _string(topic)
                         + _string(message_encoding) + _string_map(metadata or {}))
        self._channels.append(record)
        self._pending.append(record)
        self._channel_counts[channel_id] = 0
        return channel_id

    # ------------------------------------------------------------------ messages

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
                    sequence: int = 0) -> None:
        chunk = self._chunk
        if self._pending:
            self._carry_definitions()
        offset = len(chunk)
        if not self._index:   # the chunk's first message
            self._chunk_start_ns = self._chunk_end_ns = log_time
        elif log_time < self._chunk_start_ns:
            self._chunk_start_ns = log_time
        elif log_time > self._chunk_end_ns:
            self._chunk_end_ns = log_time
        chunk += MESSAGE_HEADER.pack(OP_MESSAGE, MESSAGE_FIXED_LENGTH + len(data), channel_id,
                                     sequence, log_time, publish_time)
        chunk += data
        index = self._index.get(channel_id)
        if index is None:
            index = self._index[channel_id] = []
        index += (log_time, offset)
        if len(chunk) >= self.chunk_size:
            self._finish_chunk()

    def _carry_definitions(self) -> None:
        """Schema and channel records registered since the last message go into the chunk."""
        for record in self._pending:
            self._chunk += record
        self._pending.clear()

    def _finish_chunk(self) -> None:
        chunk = self._chunk
        index = self._index
        if not index:
            return
        uncompressed = bytes(chunk)
        compressed = self._compressor.compress(uncompressed)
        start_ns, end_ns = self._chunk_start_ns, self._chunk_end_ns
        content = (_u64(start_ns) + _u64(end_ns) + _u64(len(uncompressed))
                   + _u32(zlib.crc32(uncompressed)) + _string("zstd") + _u64(len(compressed)))
        chunk_offset = self._offset
        header = struct.pack("<BQ", OP_CHUNK, len(content) + len(compressed)) + content
        self._write(header)
        self._write(compressed)
        chunk_length = self._offset - chunk_offset
        index_start = self._offset
        offsets: list[bytes] = []
        records: list[bytes] = []
        position = index_start
        for channel_id, entries in index.items():
            pairs = struct.pack(f"<{len(entries)}Q", *entries)
            record = _record(OP_MESSAGE_INDEX, _u16(channel_id) + _bytes32(pairs))
            offsets.append(_u16(channel_id) + _u64(position))
            records.append(record)
            position += len(record)
            count = len(entries) // 2
            self._channel_counts[channel_id] += count
            self._message_count += count
        for record in records:
            self._write(record)
        index_length = self._offset - index_start
        offset_map = b"".join(offsets)
        self._chunk_indexes.append(_record(OP_CHUNK_INDEX, (
            _u64(start_ns) + _u64(end_ns) + _u64(chunk_offset) + _u64(chunk_length)
            + _u32(len(offset_map)) + offset_map + _u64(index_length) + _string("zstd")
            + _u64(len(compressed)) + _u64(len(uncompressed)))))
        if len(self._chunk_indexes) == 1:
            self._start_ns, self._end_ns = start_ns, end_ns
        else:
            self._start_ns = min(self._start_ns, start_ns)
            self._end_ns = max(self._end_ns, end_ns)
        self._chunk = bytearray()
        self._index = {}

    # ------------------------------------------------------------------ attachments, metadata

    def add_attachment(self, create_time: int, log_time: int, name: str, media_type: str,
                       data: bytes) -> None:
        fields = (_u64(log_time) + _u64(create_time) + _string(name) + _string(media_type)
                  + _u64(len(data)) + data)
        record = _record(OP_ATTACHMENT, fields + _u32(zlib.crc32(fields)))
        offset = self._offset
        self._write(record)
        self._attachment_count += 1
        self._attachment_indexes.append(_record(OP_ATTACHMENT_INDEX, (
            _u64(offset) + _u64(len(record)) + _u64(log_time) + _u64(create_time)
            + _u64(len(data)) + _string(name) + _string(media_type))))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        record = _record(OP_METADATA, _string(name) + _string_map(data))
        offset = self._offset
        self._write(record)
        self._metadata_count += 1
        self._metadata_indexes.append(_record(OP_METADATA_INDEX,
                                              _u64(offset) + _u64(len(record)) + _string(name)))

    # ------------------------------------------------------------------ end

    def finish(self) -> None:
        """Write the last chunk, the summary and the footer (the stream stays open)."""
        if self._finished:
            return
        self._finished = True
        if self._pending and not self._index:
            # definitions without messages still belong in the data section
            for record in self._pending:
                self._write(record)
            self._pending.clear()
        self._finish_chunk()
        self._write(_record(OP_DATA_END, _u32(self._data_crc)), data_section=False)

        summary_start = self._offset
        summary = bytearray()
        offsets: list[bytes] = []

        def group(opcode: int, records: list[bytes]) -> None:
            if not records:
                return
            start = summary_start + len(summary)
            for record in records:
                summary.extend(record)
            offsets.append(_record(OP_SUMMARY_OFFSET, _u8(opcode) + _u64(start)
                                   + _u64(summary_start + len(summary) - start)))

        counts = b"".join(_u16(c) + _u64(n) for c, n in self._channel_counts.items() if n)
        statistics = _record(OP_STATISTICS, (
            _u64(self._message_count) + _u16(len(self._schemas)) + _u32(len(self._channels))
            + _u32(self._attachment_count) + _u32(self._metadata_count)
            + _u32(len(self._chunk_indexes)) + _u64(self._start_ns) + _u64(self._end_ns)
            + _u32(len(counts)) + counts))
        group(OP_SCHEMA, self._schemas)
        group(OP_CHANNEL, self._channels)
        group(OP_STATISTICS, [statistics])
        group(OP_CHUNK_INDEX, self._chunk_indexes)
        group(OP_ATTACHMENT_INDEX, self._attachment_indexes)
        group(OP_METADATA_INDEX, self._metadata_indexes)
        summary_offset_start = summary_start + len(summary)
        for record in offsets:
            summary.extend(record)
        footer_head = struct.pack("<BQQQ", OP_FOOTER, 20, summary_start, summary_offset_start)
        summary_crc = zlib.crc32(footer_head, zlib.crc32(summary))
        self._write(summary, data_section=False)
        self._write(footer_head + _u32(summary_crc), data_section=False)
        self._write(MAGIC, data_section=False)


__all__ = ["MAGIC", "McapWriter"]

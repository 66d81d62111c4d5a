"""rosbag2 (MCAP) bags for flex-twin: write, read, summarise, record and play.

Writing goes through the ``rosbags`` library (``rosbags.rosbag2.Writer``, format version 9,
MCAP storage): it writes ``metadata.yaml`` as Jazzy's rosbag2 does, MCAP schemas with
encoding ``ros2msg`` and the RIHS01 type hash, and the channel metadata
``offered_qos_profiles`` that rosbag2 needs to replay with the recorded QoS. Message
definitions come from the rosbags Jazzy typestore, so only the standard message packages
in :data:`STANDARD_PACKAGES` are accepted.

Crash safety: rosbags' MCAP storage writer is subclassed to write each chunk's CRC32 and to
flush each closed chunk to the file; :class:`BagWriter` closes a chunk every 0.5 s (besides
rosbags' 1 MiB limit), so a killed recorder keeps all but the last ~0.5 s.

Reading is independent of the writer and survives damage: :class:`_FileScan` walks the
``.mcap`` record by record with the ``mcap`` library's record classes, checks chunk CRCs
(``mcap.stream_reader.get_chunk_data_stream``), skips damaged byte ranges up to the next
intact chunk and reindexes a file without footer/summary or metadata.yaml (as ``ros2 bag
reindex``). What was lost is named in one :class:`BagDamageWarning` line (byte and log-time
ranges, message counts against metadata.yaml or the MCAP statistics); a bag with nothing
readable raises :class:`BagError` (one line, rc 2 in the CLI). rclpy deserializes the CDR
bytes. ``rosidl_runtime_py`` is not in the pip wheels, so :func:`get_message` resolves
``pkg/msg/Name`` with importlib as it does.

Time bases: a bag has one. The recorder's log time is the receive time (wall clock, as
rosbag2) or, with ``use_sim_time`` (``record --use-sim-time``, the default when /clock is
recorded; the twin demo), the latest /clock; ``bag info`` warns about a bag that mixes
sim-time and wall-clock log times and ``play`` refuses it.

Times are integer nanoseconds (``t_ns``) in the bag; summaries are in seconds (``_s``).
rclpy is imported lazily (inside functions) so that importing this module never starts ROS.
"""
from __future__ import annotations

import importlib
import threading
import time
from functools import lru_cache
from pathlib import Path

STANDARD_PACKAGES = ("sensor_msgs", "std_msgs", "geometry_msgs", "trajectory_msgs",
                     "nav_msgs", "visualization_msgs", "rosgraph_msgs", "std_srvs",
                     "builtin_interfaces")


class BagError(ValueError):
    """A bag that cannot be written or read as asked (the message names path/topic/value)."""


def get_message(type_str: str):
    """The rclpy message class of ``pkg/msg/Name`` (a standard package only)."""
    parts = type_str.split("/")
    if len(parts) != 3 or parts[1] != "msg" or not all(parts):
        raise BagError(f"message type {type_str!r}: expected 'package/msg/Name'")
    if parts[0] not in STANDARD_PACKAGES:
        raise BagError(f"message type {type_str!r}: package {parts[0]!r} is not one of the "
                       f"standard packages {', '.join(STANDARD_PACKAGES)}")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.msg"), parts[2])
    except (ImportError, AttributeError):
        raise BagError(f"message type {type_str!r}: not found in the installed "
                       f"{parts[0]} package") from None


def type_string(msg_or_class) -> str:
    """``pkg/msg/Name`` of an rclpy message object or class."""
    cls = msg_or_class if isinstance(msg_or_class, type) else type(msg_or_class)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


@lru_cache(maxsize=1)
def jazzy_typestore():
    """The rosbags typestore of ROS 2 Jazzy (message definitions and type hashes)."""
    from rosbags.typesys import Stores, get_typestore
    return get_typestore(Stores.ROS2_JAZZY)


def _qos_to_rosbags(qos):
    """rclpy ``QoSProfile`` -> ``rosbags.interfaces.Qos`` (same enum values as rmw)."""
    from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                    QosReliability, QosTime)

    def t(duration):
        ns = int(duration.nanoseconds)
        return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)
    return Qos(QosHistory(int(qos.history)), int(qos.depth),
               QosReliability(int(qos.reliability)), QosDurability(int(qos.durability)),
               t(qos.deadline), t(qos.lifespan), QosLiveliness(int(qos.liveliness)),
               t(qos.liveliness_lease_duration), bool(qos.avoid_ros_namespace_conventions))


def _exact_cdr(data: bytes, type_str: str) -> bytes:
    """``data`` cut to the end of its CDR payload.

    ``rclpy.serialization.serialize_message`` (rmw_fastrtps) returns a buffer of the
    *estimated* size, which exceeds the payload (by 8 bytes for a JointState with empty
    sequences; the surplus bytes are uninitialised). rclpy and rosbag2 ignore the surplus,
    the ``rosbags`` reader rejects more than 3 trailing bytes. The payload end is found by
    decoding with the rosbags Jazzy typestore, which also checks the bytes fit the type.
    """
    msgdef = jazzy_typestore().get_msgdef(type_str)
    decode = msgdef.deserialize_cdr_le if data[1] else msgdef.deserialize_cdr_be
    try:
        _, end = decode(memoryview(data)[4:], 0, msgdef.cls, jazzy_typestore())
    except Exception as exc:  # struct.error, ValueError, ... : bytes do not fit the type
        raise BagError(f"CDR bytes do not decode as {type_str}: {exc}") from exc
    return data[:4 + end]


class BagDamageWarning(UserWarning):
    """A bag read only in part (damaged, truncated, not closed, no metadata.yaml): the
    message names what was lost (byte range, time range, message counts)."""


_MAGIC = b"\x89MCAP0\r\n"
_OP_HEADER, _OP_FOOTER, _OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE, _OP_CHUNK = 1, 2, 3, 4, 5, 6
_OP_MESSAGE_INDEX, _OP_CHUNK_INDEX, _OP_STATISTICS, _OP_DATA_END = 7, 8, 11, 15
_FOOTER_LEN = 1 + 8 + 20  # opcode, length, summary_start, summary_offset_start, summary_crc


def _u64(data, pos: int) -> int:
    return int.from_bytes(data[pos:pos + 8], "little")


def _stream(body):
    from io import BytesIO

    from mcap.data_stream import ReadDataStream
    return ReadDataStream(BytesIO(body))


def _plausible_record(data, pos: int, stop: int, ops) -> int | None:
    """End offset of a well-formed MCAP record at ``pos`` (opcode in ``ops``, length inside
    ``stop``; a chunk also has to have self-consistent header fields), else None."""
    if pos + 9 > stop or data[pos] not in ops:
        return None
    end = pos + 9 + _u64(data, pos + 1)
    if end > stop:
        return None
    if data[pos] == _OP_CHUNK:
        body = pos + 9
        if end - body < 40:
            return None
        start_t, end_t = _u64(data, body), _u64(data, body + 8)
        comp_len = int.from_bytes(data[body + 28:body + 32], "little")
        if comp_len > 4 or bytes(data[body + 32:body + 32 + comp_len]) not in (
                b"", b"zstd", b"lz4") or (start_t > end_t and end_t != 0):
            return None
        if _u64(data, body + 32 + comp_len) != end - (body + 40 + comp_len):
            return None
    return end


class _FileScan:
    """Record-by-record read of one ``.mcap`` file that survives damage.

    The data section is walked record by record (as ``ros2 bag reindex`` does); each chunk
    is decompressed and, when it carries a CRC, checked with mcap's
    ``get_chunk_data_stream(validate_crc=True)``. A damaged byte range is skipped up to the
    next well-formed chunk; a chunk failing its CRC is dropped whole. Inside a chunk without
    a CRC (bags written before chunk CRCs were added), the chunk's message index records are
    used to resume after a damaged record. The summary (found through the footer) supplies
    schemas, channels, chunk indexes and message counts when the data section lost them.
    ``lost`` lists (what, t0_ns, t1_ns, count or None) and ``problems`` other findings.
    """

    def __init__(self, file: Path):
        self.file = file
        self.schemas, self.channels = {}, {}
        self.messages = []      # (log_time, channel_id, data), file order
        self.lost, self.problems = [], []
        self.stats_counts = None  # {channel_id: count} of the summary's Statistics
        self.closed = False       # footer and summary present
        data = file.read_bytes()
        if not data:
            raise BagError(f"{file.name}: empty file (0 bytes): nothing was written")
        if data[:8] != _MAGIC:
            raise BagError(f"{file.name}: not an MCAP file (first bytes "
                           f"{bytes(data[:8])!r})")
        self._good_chunks = []   # (file offset, t0, t1) of chunks read
        self._handled = set()    # file offsets of chunks read or reported lost
        stop = self._read_summary(data)
        self._read_data(data, stop)
        if not self.channels and not self.messages:
            if self.lost:
                raise BagError(f"{file.name}: no intact topic or message (damaged beyond "
                               f"repair: {'; '.join(self._describe())})")
            if not self.closed:
                raise BagError(f"{file.name}: no topic or message: the file ends after "
                               "the MCAP header (recording stopped before its first chunk)")

    # -- summary --------------------------------------------------------------------------
    def _read_summary(self, data) -> int:
        """Parse the footer and summary; returns where the data section ends."""
        from mcap.records import Channel, ChunkIndex, Footer, Schema, Statistics
        n = len(data)
        fpos = n - 8 - _FOOTER_LEN
        self.chunk_indexes = []
        if not (fpos >= 8 and data[-8:] == _MAGIC and data[fpos] == _OP_FOOTER
                and _u64(data, fpos + 1) == 20):
            self.problems.append("no footer/summary (not closed: recording killed or "
                                 "crashed?); reindexed from the records")
            return n
        footer = Footer.read(_stream(data[fpos + 9:fpos + _FOOTER_LEN]))
        if footer.summary_start == 0:
            self.closed = True
            return fpos
        if not 8 <= footer.summary_start <= fpos:
            self.problems.append(f"footer points outside the file (summary at byte "
                                 f"{footer.summary_start}); reindexed from the records")
            return fpos
        pos, summary = footer.summary_start, {}
        readers = {_OP_SCHEMA: Schema, _OP_CHANNEL: Channel, _OP_CHUNK_INDEX: ChunkIndex,
                   _OP_STATISTICS: Statistics}
        while pos < fpos:
            end = _plausible_record(data, pos, fpos, set(range(1, 16)))
            if end is None:
                self.problems.append(f"summary damaged at byte {pos}; reindexed from the "
                                     "records")
                return footer.summary_start
            if data[pos] in readers:
                try:
                    rec = readers[data[pos]].read(_stream(data[pos + 9:end]))
                except Exception:  # a damaged summary record: ignore the summary
                    self.problems.append(f"summary record at byte {pos} damaged; "
                                         "reindexed from the records")
                    return footer.summary_start
                summary.setdefault(data[pos], []).append(rec)
            pos = end
        for s in summary.get(_OP_SCHEMA, []):
            self.schemas[s.id] = s
        for c in summary.get(_OP_CHANNEL, []):
            self.channels[c.id] = c
        self.chunk_indexes = summary.get(_OP_CHUNK_INDEX, [])
        if summary.get(_OP_STATISTICS):
            self.stats_counts = dict(summary[_OP_STATISTICS][0].channel_message_counts)
        self.closed = True
        return footer.summary_start

    # -- data section ---------------------------------------------------------------------
    def _read_data(self, data, stop: int) -> None:
        from mcap.records import Channel, Chunk, Message, MessageIndex, Schema
        pos, ops = 8, set(range(1, 16))
        while pos < stop:
            end = _plausible_record(data, pos, stop, ops)
            if end is None:
                pos = self._skip_damage(data, pos, stop)
                continue
            op = data[pos]
            if op in (_OP_DATA_END, _OP_FOOTER):
                break
            body = data[pos + 9:end]
            try:
                if op == _OP_SCHEMA:
                    s = Schema.read(_stream(body))
                    self.schemas.setdefault(s.id, s)
                elif op == _OP_CHANNEL:
                    c = Channel.read(_stream(body))
                    self.channels.setdefault(c.id, c)
                elif op == _OP_MESSAGE:
                    m = Message.read(_stream(body), len(body))
                    self.messages.append((m.log_time, m.channel_id, bytes(m.data)))
                elif op == _OP_CHUNK:
                    chunk = Chunk.read(_stream(body))
                    index, after = [], end  # the chunk's message index records follow it
                    while (nxt := _plausible_record(data, after, stop, {_OP_MESSAGE_INDEX})):
                        try:
                            index += MessageIndex.read(_stream(data[after + 9:nxt])).records
                        except Exception:
                            break
                        after = nxt
                    self._read_chunk(pos, chunk, sorted(index, key=lambda r: r[1]))
                    end = after
            except BagError:
                raise
            except Exception as exc:  # a record that does not decode: skip it
                self.problems.append(f"record at byte {pos} does not decode ({exc})")
            pos = end
        for ci in self.chunk_indexes:  # chunks the summary knows that were not read
            if ci.chunk_start_offset not in self._handled:
                self.lost.append((f"chunk at byte {ci.chunk_start_offset} missing",
                                  ci.message_start_time, ci.message_end_time, None,
                                  ci.chunk_start_offset))

    def _skip_damage(self, data, pos: int, stop: int) -> int:
        """Skip a damaged byte range up to the next well-formed chunk (or the data end)."""
        nxt, t0, t1 = pos + 1, None, None
        if data[pos] == _OP_CHUNK and pos + 9 + 16 <= stop:  # a readable chunk header
            t0, t1 = _u64(data, pos + 9), _u64(data, pos + 17)
            if t0 > t1:
                t0 = t1 = None
        while nxt < stop:
            nxt = data.find(_OP_CHUNK.to_bytes(1, "little"), nxt, stop)
            if nxt < 0:
                nxt = stop
                break
            if _plausible_record(data, nxt, stop, {_OP_CHUNK}) is not None:
                break
            nxt += 1
        for ci in self.chunk_indexes:  # the summary names the chunks in the damaged range
            if pos <= ci.chunk_start_offset < nxt or (
                    ci.chunk_start_offset < pos < ci.chunk_start_offset + ci.chunk_length):
                self._handled.add(ci.chunk_start_offset)
                t0 = ci.message_start_time if t0 is None else min(t0, ci.message_start_time)
                t1 = ci.message_end_time if t1 is None else max(t1, ci.message_end_time)
        what = (f"bytes {pos}-{nxt} truncated" if nxt >= len(data) else
                f"bytes {pos}-{nxt} damaged")
        self.lost.append((what, t0, t1, None, pos))
        return nxt

    def _read_chunk(self, pos: int, chunk, index) -> None:
        """Messages of one chunk; CRC failure drops it, damage without CRC resumes at the
        next indexed message."""
        from mcap.records import Channel, Message, Schema
        from mcap.stream_reader import get_chunk_data_stream
        t0, t1 = chunk.message_start_time, chunk.message_end_time
        try:
            stream, size = get_chunk_data_stream(chunk, validate_crc=True)
            raw = stream.read(size)
        except Exception as exc:  # CRCValidationError, decompression error
            reason = "fails its CRC" if "crc" in str(exc).lower() else f"unreadable ({exc})"
            if t0 > t1:  # a chunk of schemas/channels only
                t0 = t1 = None
            self.lost.append((f"chunk at byte {pos} {reason}", t0, t1,
                              len(index) if index else None, pos))
            self._handled.add(pos)
            return
        verified = chunk.uncompressed_crc != 0
        offsets = [off for _, off in index]
        p, got, damaged_at, last_end, last_message = 0, 0, None, -1, None
        while p < size:
            end = _plausible_record(raw, p, size, {_OP_SCHEMA, _OP_CHANNEL, _OP_MESSAGE})
            rec = None
            if end is not None:
                try:
                    body = raw[p + 9:end]
                    if raw[p] == _OP_MESSAGE:
                        rec = Message.read(_stream(body), len(body))
                        if not verified and (rec.channel_id not in self.channels
                                             or not t0 <= rec.log_time <= t1):
                            rec = None
                    else:
                        rec = (Schema if raw[p] == _OP_SCHEMA else Channel).read(
                            _stream(body))
                except Exception:
                    rec = None
            if rec is None:  # damage inside the chunk: resume at the next indexed message
                if damaged_at is None:
                    damaged_at = p
                    if last_end == p and last_message is not None:
                        self.messages.pop()  # the message just before the damage may have
                        got -= 1             # a damaged tail: drop it too
                        damaged_at = last_message
                later = [off for off in offsets if off > p]
                if not later:
                    break
                p = later[0]
                continue
            last_message = None
            if isinstance(rec, Message):
                self.messages.append((rec.log_time, rec.channel_id, bytes(rec.data)))
                got += 1
                last_message = p
            elif isinstance(rec, Schema):
                self.schemas.setdefault(rec.id, rec)
            else:
                self.channels.setdefault(rec.id, rec)
            p = last_end = end
        self._handled.add(pos)
        self._good_chunks.append((pos, t0, t1))
        if damaged_at is not None:
            missing = (len(index) - got) if index else None
            if missing != 0:
                lost_t = [t for t, off in index if off >= damaged_at] if index else []
                self.lost.append((f"chunk at byte {pos} damaged inside (no CRC)",
                                  min(lost_t, default=t0), max(lost_t, default=t1),
                                  missing, pos))

    def _describe(self) -> list[str]:
        """One phrase per lost range: bytes, message count, log-time range."""
        out = []
        good = sorted(self._good_chunks)
        for what, t0, t1, count, pos in self.lost:
            n = "an unknown number of messages" if count is None else f"{count} message(s)"
            if t0 is not None:
                when = f", log times {t0 * 1e-9:.3f}-{t1 * 1e-9:.3f} s"
            else:  # between the neighbouring intact chunks
                before = [g[2] for g in good if g[0] < pos]
                after = [g[1] for g in good if g[0] > pos]
                when = (f", log times after {before[-1] * 1e-9:.3f} s" if before else "") + (
                    f"{',' if before else ', log times'} before {after[0] * 1e-9:.3f} s"
                    if after else "")
            out.append(f"{what}: {n} lost{when}")
        return out


def _mcap_files(path: Path, meta: dict | None, problems: list) -> list[Path]:
    """The bag's .mcap files: metadata.yaml's ``relative_file_paths``, else (noted in
    ``problems`` when metadata.yaml lists missing files) ``*.mcap``."""
    if not path.is_dir():
        raise BagError(f"bag {path}: no such directory")
    files = []
    if meta is not None:
        if meta.get("storage_identifier") != "mcap":
            raise BagError(f"bag {path}: storage_identifier "
                           f"{meta.get('storage_identifier')!r}, only 'mcap' is supported")
        listed = meta.get("relative_file_paths")
        files = [path / str(f) for f in (listed if isinstance(listed, list) else [])]
        missing = [f.name for f in files if not f.is_file()]
        if missing and sorted(path.glob("*.mcap")):
            problems.append(f"metadata.yaml lists missing file(s) {missing}; read "
                            f"{[f.name for f in sorted(path.glob('*.mcap'))]} instead")
            files = []
    if not files:
        files = sorted(path.glob("*.mcap"))
    if not files or not all(f.is_file() for f in files):
        raise BagError(f"bag {path}: no readable .mcap file (looked for "
                       f"{[str(f.name) for f in files] or '*.mcap'})")
    return files


def _metadata(path: Path, problems: list | None = None) -> dict | None:
    """``rosbag2_bagfile_information`` of ``path/metadata.yaml`` or None when absent (or,
    with a ``problems`` list to note it in, unreadable)."""
    import yaml
    meta_path = Path(path) / "metadata.yaml"
    if not meta_path.is_file():
        return None
    try:
        with open(meta_path, encoding="utf8") as f:
            meta = (yaml.safe_load(f) or {}).get("rosbag2_bagfile_information", {})
        if not isinstance(meta, dict):
            raise ValueError("no rosbag2_bagfile_information mapping")
        return meta
    except (yaml.YAMLError, ValueError, AttributeError, UnicodeDecodeError) as exc:
        if problems is None:
            raise BagError(f"bag {path}: metadata.yaml unreadable: "
                           f"{str(exc).splitlines()[0]}") from None
        problems.append(f"metadata.yaml unreadable ({str(exc).splitlines()[0]}); "
                        "read the .mcap alone")
        return None


_WARNING_REGISTRY: dict = {}


class _Bag:
    """A bag read in full: ``types`` {topic: type}, ``messages`` [(topic, type, t_ns, data,
    channel metadata)] in log-time order per file, ``warnings`` (one line each)."""

    def __init__(self, path):
        self.path = path = Path(path)
        problems = []
        if not path.is_dir():
            raise BagError(f"bag {path}: no such directory")
        self.meta = _metadata(path, problems)
        if self.meta is None and not problems:
            problems.append("no metadata.yaml; read the .mcap alone")
        files = _mcap_files(path, self.meta, problems)
        self.types, self.messages, read_counts = {}, [], {}
        stats, lost = {}, []
        for file in files:
            try:
                scan = _FileScan(file)
            except BagError as exc:
                raise BagError(f"bag {path}: {exc}") from None
            except OSError as exc:
                raise BagError(f"bag {path}: {file.name}: {exc.strerror or exc}") from None
            file_msgs = []
            unknown = 0
            for log_time, cid, data in scan.messages:
                channel = scan.channels.get(cid)
                schema = None if channel is None else scan.schemas.get(channel.schema_id)
                if schema is None:
                    unknown += 1
                    continue
                if channel.message_encoding != "cdr":
                    raise BagError(f"bag {file}: topic {channel.topic} has encoding "
                                   f"{channel.message_encoding!r}, expected 'cdr'")
                file_msgs.append((channel.topic, schema.name, log_time, data,
                                  channel.metadata))
            for channel in scan.channels.values():
                schema = scan.schemas.get(channel.schema_id)
                if schema is not None:
                    self.types.setdefault(channel.topic, schema.name)
            if unknown:
                problems.append(f"{file.name}: {unknown} message(s) on channels whose "
                                "definition was lost")
            file_msgs.sort(key=lambda m: m[2])  # stable: file order among equal times
            self.messages += file_msgs
            for m in file_msgs:
                read_counts[m[0]] = read_counts.get(m[0], 0) + 1
            if scan.stats_counts is not None:
                for cid, count in scan.stats_counts.items():
                    if cid in scan.channels:
                        topic = scan.channels[cid].topic
                        stats[topic] = stats.get(topic, 0) + count
            problems += [f"{file.name}: {p}" for p in scan.problems]
            lost += [f"{file.name}: {d}" for d in scan._describe()]
        self.read_counts = {t: read_counts.get(t, 0) for t in self.types}
        expected, source = None, None
        if self.meta is not None and self.meta.get("topics_with_message_count"):
            try:
                expected = {t["topic_metadata"]["name"]: int(t.get("message_count", 0))
                            for t in self.meta["topics_with_message_count"]}
                source = "metadata.yaml"
            except (KeyError, TypeError, ValueError, AttributeError):
                problems.append("metadata.yaml: topics_with_message_count malformed")
        if expected is None and stats:
            expected, source = stats, "the MCAP statistics"
        self.expected = expected
        if self.meta is not None:  # the time range metadata.yaml promises
            try:
                m_start = int(self.meta["starting_time"]["nanoseconds_since_epoch"])
                m_end = m_start + int(self.meta["duration"]["nanoseconds"])
            except (KeyError, TypeError, ValueError):
                m_start = m_end = None
            times = [m[2] for m in self.messages]
            if m_start is not None and times and max(times) < m_end:
                lost.append(f"messages after log time {max(times) * 1e-9:.3f} s missing "
                            f"(metadata.yaml: the bag ends at {m_end * 1e-9:.3f} s)")
            if m_start is not None and times and min(times) > m_start:
                lost.append(f"messages before log time {min(times) * 1e-9:.3f} s missing "
                            f"(metadata.yaml: the bag starts at {m_start * 1e-9:.3f} s)")
        short = []
        if expected is not None:
            for topic in sorted(set(expected) | set(self.read_counts)):
                want, got = expected.get(topic), self.read_counts.get(topic, 0)
                if want is None or want != got:
                    short.append(f"{topic} {got} of {'?' if want is None else want}")
        self.warnings = []
        if lost or short or problems:
            total = sum(self.read_counts.values())
            parts = problems + lost
            if short:
                parts.append(f"read {total} of {sum(expected.values())} message(s) "
                             f"listed in {source} ({', '.join(short)})")
            elif expected is not None:
                parts.append(f"all {total} message(s) listed in {source} read")
            else:
                parts.append(f"read {total} message(s); counts not checked (neither "
                             "metadata.yaml nor MCAP statistics)")
            self.warnings.append(f"bag {path}: " + "; ".join(parts))
        import warnings
        for text in self.warnings:  # one location: shown once per text by default (a
            warnings.warn_explicit(  # caller reading topic_types, then read_bag)
                text, BagDamageWarning, __file__, 0, module=__name__,
                registry=_WARNING_REGISTRY)


def iter_raw(path, topics=None):
    """(topic, type_str, t_ns, cdr_bytes, channel_metadata) in log-time order per file.

    A damaged bag yields what is intact and warns (:class:`BagDamageWarning`) with the lost
    byte/time range and the message counts against metadata.yaml; a bag with nothing
    readable raises :class:`BagError` (one line)."""
    bag = _Bag(path)
    wanted = None if topics is None else set(topics)
    if wanted is not None:
        missing = wanted - set(bag.types)
        if missing:
            raise BagError(f"bag {path}: no topic(s) {sorted(missing)}")
    for message in bag.messages:
        if wanted is None or message[0] in wanted:
            yield message


def topic_types(path) -> dict[str, str]:
    """``{topic: type_str}`` of every channel in the bag's MCAP files."""
    return dict(_Bag(path).types)


def read_bag(path, topics=None):
    """Iterate ``(topic, type_str, t_ns, message)`` with rclpy-deserialized messages."""
    from rclpy.serialization import deserialize_message
    classes = {}
    for topic, type_str, t_ns, data, _ in iter_raw(path, topics):
        if type_str not in classes:
            classes[type_str] = get_message(type_str)
        yield topic, type_str, t_ns, deserialize_message(data, classes[type_str])


def bag_info(path) -> dict:
    """JSON-able summary: duration, start/end and per topic type, count and frequency.

    ``frequency_hz`` = (count - 1) / (last - first stamp) of that topic (None if < 2
    messages), i.e. the mean rate between its first and last message. ``warnings``: the
    damage found (see :func:`iter_raw`), one line each.
    """
    path = Path(path)
    bag = _Bag(path)
    stamps = {name: [] for name in bag.types}
    for topic, _type, t_ns, _data, _meta in bag.messages:
        stamps[topic].append(t_ns)
    every = [t for ts in stamps.values() for t in ts]
    start, end = (min(every), max(every)) if every else (0, 0)
    meta = bag.meta or {}
    topics = []
    for name, type_str in sorted(bag.types.items()):
        ts, span = stamps[name], max(stamps[name] or [0]) - min(stamps[name] or [0])
        topics.append({"name": name, "type": type_str, "count": len(ts),
                       "frequency_hz": (len(ts) - 1) / (span * 1e-9) if span else None})
    warnings_ = list(bag.warnings)
    mixed = _mixed_time_bases(stamps)
    if mixed:
        warnings_.append(f"bag {path}: {mixed}")
    return {"path": str(path), "version": meta.get("version"),
            "storage_identifier": meta.get("storage_identifier", "mcap"),
            "duration_s": (end - start) * 1e-9, "start_time_s": start * 1e-9,
            "end_time_s": end * 1e-9, "message_count": sum(t["count"] for t in topics),
            "topics": topics, "warnings": warnings_}


SIM_TIME_LIMIT_NS = 10**9 * 86400 * 365 * 10  # log times below 10 years: not the wall clock


def _mixed_time_bases(stamps: dict) -> str | None:
    """A sentence when some topics' log times are sim time (from ~0) and others wall-clock
    time (since 1970), else None."""
    sim = sorted(t for t, ts in stamps.items() if ts and max(ts) < SIM_TIME_LIMIT_NS)
    wall = sorted(t for t, ts in stamps.items() if ts and min(ts) >= SIM_TIME_LIMIT_NS)
    if sim and wall:
        return (f"mixed time bases: log times of {', '.join(sim)} are sim time (from 0), "
                f"of {', '.join(wall)} wall-clock time (recorded without --use-sim-time?)")
    return None


def _flushing_mcap_writer():
    """rosbags' MCAP storage writer with chunk CRCs, each chunk written through to the file.

    rosbags writes ``uncompressed_crc = 0`` (no CRC) and leaves closed chunks in the file
    object's buffer; this subclass patches the CRC32 of the chunk's records into the Chunk
    record and flushes the file, so that a reader can tell a damaged chunk and a killed
    recorder leaves every closed chunk on disk (see :meth:`BagWriter.flush`)."""
    import struct
    import zlib

    from rosbags.rosbag2.storage_mcap import McapWriter

    class FlushingMcapWriter(McapWriter):
        def close_chunk(self) -> None:
            crc = zlib.crc32(self.chunk.bio.getbuffer())
            start = self.bio.tell()
            super().close_chunk()
            end = self.bio.tell()
            self.bio.seek(start + 1 + 8 + 24)  # opcode, length, start/end time, size
            self.bio.write(struct.pack("<I", crc))
            self.bio.seek(end)
            self.bio.flush()
    return FlushingMcapWriter


class BagWriter:
    """A new rosbag2 bag (format version 9) written with ``rosbags``; thread-safe.

    Use as a context manager: the bag is closed (MCAP summary and metadata.yaml written)
    on leaving the block, also on an exception or KeyboardInterrupt, so that a stopped
    recording remains a complete bag. ``close()`` is idempotent.

    Crash safety: the open MCAP chunk is closed and written to the file (with its CRC) once
    its first message is ``flush_interval_s`` old, at the next :meth:`write` or
    :meth:`flush_if_due` (the recorder calls it every 50 ms), besides rosbags' 1 MiB limit.
    A killed recorder thus loses at most the last ``flush_interval_s`` (plus 50 ms) of
    messages; the reader reindexes a file without summary or metadata.yaml.
    """

    def __init__(self, path, *, storage: str = "mcap", flush_interval_s: float = 0.5):
        from rosbags.rosbag2 import StoragePlugin, Writer
        if storage != "mcap":
            raise BagError(f"bag {path}: storage {storage!r} unsupported (only 'mcap')")
        self.path = Path(path)
        if self.path.exists():
            if not self.path.is_dir():
                raise BagError(f"bag {self.path}: exists and is not a directory")
            if any(self.path.iterdir()):
                raise BagError(f"bag {self.path}: directory exists and is not empty; "
                               "choose a new output directory")
            self.path.rmdir()  # rosbags creates the directory itself
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._writer = Writer(self.path, version=9, storage_plugin=StoragePlugin.MCAP)
        self._writer.STORAGE_PLUGINS = {StoragePlugin.MCAP: _flushing_mcap_writer()}
        self._writer.open()
        self.flush_interval_s = float(flush_interval_s)
        self._chunk_t0 = None  # monotonic time of the first message of the open chunk
        self._lock = threading.Lock()
        self._connections = {}
        self.counts: dict[str, int] = {}
        self.closed = False

    def add_topic(self, name: str, msg_type_str: str, qos=None, type_hash: str | None = None):
        """Declare a topic; ``qos`` is a ``QoSProfile`` or a list of them (offered QoS)."""
        from rclpy.qos import QoSProfile
        get_message(msg_type_str)  # a standard, installed type
        store = jazzy_typestore()
        if msg_type_str not in store.types:
            raise BagError(f"topic {name}: type {msg_type_str} not in the Jazzy typestore")
        profiles = [QoSProfile(depth=10)] if qos is None else (
            list(qos) if isinstance(qos, (list, tuple)) else [qos])
        msgdef, _ = store.generate_msgdef(msg_type_str, ros_version=2)
        with self._lock:
            if name in self._connections:
                raise BagError(f"bag {self.path}: topic {name} added twice")
            self._connections[name] = self._writer.add_connection(
                name, msg_type_str, msgdef=msgdef,
                rihs01=type_hash or store.hash_rihs01(msg_type_str),
                offered_qos_profiles=[_qos_to_rosbags(q) for q in profiles])
            self.counts[name] = 0

    def write(self, topic: str, msg_or_bytes, t_ns: int) -> None:
        """Write one message (an rclpy message object or CDR bytes) at ``t_ns``."""
        if not isinstance(t_ns, int) or t_ns < 0:
            raise BagError(f"topic {topic}: t_ns must be a non-negative int, got {t_ns!r}")
        if isinstance(msg_or_bytes, (bytes, bytearray, memoryview)):
            data = bytes(msg_or_bytes)
        else:
            from rclpy.serialization import serialize_message
            if topic not in self._connections:
                self.add_topic(topic, type_string(msg_or_bytes))
            data = _exact_cdr(serialize_message(msg_or_bytes), type_string(msg_or_bytes))
        if topic not in self._connections:
            raise BagError(f"bag {self.path}: topic {topic} not added (add_topic first)")
        with self._lock:
            if self.closed:
                raise BagError(f"bag {self.path}: already closed")
            self._writer.write(self._connections[topic], t_ns, data)
            self.counts[topic] += 1
            if not self._writer.storage.chunk.msgs:  # rosbags closed the chunk (1 MiB)
                self._chunk_t0 = None
            elif self._chunk_t0 is None:
                self._chunk_t0 = time.monotonic()
            elif time.monotonic() - self._chunk_t0 >= self.flush_interval_s:
                self._flush_locked()

    def _flush_locked(self) -> None:
        storage = self._writer.storage
        if storage is not None and storage.chunk.msgs:
            storage.close_chunk()
        self._chunk_t0 = None

    def flush(self) -> None:
        """Close the open chunk and write it to the file now (no-op without messages)."""
        with self._lock:
            if not self.closed:
                self._flush_locked()

    def flush_if_due(self) -> None:
        """:meth:`flush` when the open chunk's first message is ``flush_interval_s`` old."""
        if self._chunk_t0 is not None and (
                time.monotonic() - self._chunk_t0 >= self.flush_interval_s):
            self.flush()

    def close(self) -> None:
        """Finish the MCAP file and write metadata.yaml (idempotent)."""
        with self._lock:
            if not self.closed:
                self.closed = True
                self._writer.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> bool:
        self.close()
        return False


def discover_types(node, names, timeout_s: float = 5.0, stop_event=None) -> dict[str, str]:
    """``{name: type}`` of the given topics, polling the graph up to ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        graph = dict(node.get_topic_names_and_types())
        missing = [n for n in names if n not in graph]
        if not missing:
            return {n: graph[n][0] for n in names}
        if time.monotonic() > deadline or (stop_event is not None and stop_event.is_set()):
            raise BagError(f"topic(s) {missing} not on the graph after {timeout_s} s "
                           "(give the type as NAME=pkg/msg/Type or start the publisher)")
        time.sleep(0.05)


class Recorder:
    """Records topics of the graph into a :class:`BagWriter` with raw subscriptions.

    ``topics`` maps names to types, or lists names whose types are looked up on the graph
    (waiting up to ``discovery_timeout_s``).

    Log time (one time base per bag): by default the node clock at the callback (the
    receive time, as rosbag2 records). With ``use_sim_time`` the simulation time of the
    latest /clock message instead (``ros2 bag record --use-sim-time``): /clock itself is
    stamped with its own value, messages received before the first /clock with the first
    /clock value. Topics in ``use_header_stamp`` are stamped with their ``header.stamp``
    (the same time base as /clock for a lockstep suite).

    QoS as rosbag2 adapts it: a topic is subscribed once a publisher is on the graph (a
    0.1 s steady timer polls for it), RELIABLE unless a publisher offers BEST_EFFORT, and
    TRANSIENT_LOCAL when all publishers offer it, so that latched messages (published
    before the recorder started) are recorded. Topics without a publisher until
    :meth:`stop` are declared in the bag with no messages.
    """

    def __init__(self, node, bag_writer: BagWriter, topics, *, use_header_stamp=(),
                 depth: int = 100, discovery_timeout_s: float = 5.0,
                 use_sim_time: bool = False):
        from rclpy.clock import Clock, ClockType
        self.node, self.writer, self.depth = node, bag_writer, depth
        self.use_header_stamp = set(use_header_stamp)
        self.use_sim_time = use_sim_time
        self._subs, self._pending, self._types = {}, {}, {}
        self._sim_ns = None   # the latest /clock (use_sim_time)
        self._early = []      # (name, data, receive ns) before the first /clock
        self._clock_sub = None
        if use_sim_time:
            from rclpy.qos import QoSProfile, ReliabilityPolicy
            from rosgraph_msgs.msg import Clock as ClockMsg
            # BEST_EFFORT, VOLATILE: compatible with every /clock publisher
            self._clock_sub = node.create_subscription(
                ClockMsg, "/clock", self._on_clock,
                QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT))
        self._timer = node.create_timer(0.1, self._subscribe_pending,
                                        clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.add_topics(dict(topics) if isinstance(topics, dict) else discover_types(
            node, list(topics), discovery_timeout_s))

    def add_topics(self, types: dict[str, str]) -> list[str]:
        """Record ``{name: type}`` topics not yet recorded; returns the new names."""
        new = [n for n in types if n not in self._types]
        for name in new:
            get_message(types[name])  # a standard, installed type
            self._types[name] = types[name]
            self._pending[name] = types[name]
        self._subscribe_pending()
        return new

    def _subscribe_pending(self) -> None:
        """Subscribe the pending topics that have a publisher, with its QoS."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        for name, type_str in list(self._pending.items()):
            offered = [i.qos_profile for i in self.node.get_publishers_info_by_topic(name)]
            if not offered:
                continue
            del self._pending[name]
            qos = QoSProfile(depth=self.depth)
            if any(q.reliability == ReliabilityPolicy.BEST_EFFORT for q in offered):
                qos.reliability = ReliabilityPolicy.BEST_EFFORT
            if all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered):
                qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
            self.writer.add_topic(name, type_str, qos=offered)
            cls = get_message(type_str)
            self._subs[name] = self.node.create_subscription(
                cls, name, self._callback(name, cls), qos, raw=True)

    @property
    def sim_time_ns(self) -> int | None:
        """The latest /clock received (``use_sim_time``), None before the first."""
        return self._sim_ns

    def _on_clock(self, msg) -> None:
        t_ns = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
        first = self._sim_ns is None
        self._sim_ns = t_ns if first else max(self._sim_ns, t_ns)
        if first:
            self._write_early(t_ns)

    def _write_early(self, t_ns=None) -> None:
        early, self._early = self._early, []
        for name, data, received_ns in early:
            if not self.writer.closed:
                self.writer.write(name, data, received_ns if t_ns is None else t_ns)

    def _callback(self, name, cls):
        from rclpy.serialization import deserialize_message
        by_header = name in self.use_header_stamp
        is_clock = self.use_sim_time and name == "/clock" and not by_header

        def callback(data):
            if by_header:
                stamp = deserialize_message(data, cls).header.stamp
                t_ns = stamp.sec * 1_000_000_000 + stamp.nanosec
            elif is_clock:
                clock = deserialize_message(data, cls).clock
                t_ns = clock.sec * 1_000_000_000 + clock.nanosec
            elif self.use_sim_time:
                if self._sim_ns is None:  # stamped with the first /clock when it comes
                    self._early.append((name, data, self.node.get_clock().now().nanoseconds))
                    return
                t_ns = self._sim_ns
            else:
                t_ns = self.node.get_clock().now().nanoseconds
            if not self.writer.closed:
                self.writer.write(name, data, t_ns)
        return callback

    def stop(self) -> None:
        """Destroy the subscriptions and declare topics that never had a publisher (the
        writer stays open; the caller closes it). Messages held for the first /clock are
        written with their receive time when no /clock came."""
        self._write_early(None)
        if not self.writer.closed:
            for name, type_str in self._pending.items():
                self.writer.add_topic(name, type_str)
        self._pending = {}
        for sub in self._subs.values():
            self.node.destroy_subscription(sub)
        self._subs = {}
        if self._clock_sub is not None:
            self.node.destroy_subscription(self._clock_sub)
            self._clock_sub = None
        if self._timer is not None:
            self.node.destroy_timer(self._timer)
            self._timer = None


def _playback_qos(offered_yaml: str | None, depth: int | None):
    """Publisher QoS from a channel's ``offered_qos_profiles`` (rosbag2's rule): RELIABLE
    and TRANSIENT_LOCAL only when every recorded publisher offered them."""
    import yaml
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    profiles = yaml.safe_load(offered_yaml) if offered_yaml else None
    profiles = profiles if isinstance(profiles, list) else []

    def all_are(key, name, value):
        return bool(profiles) and all(str(p.get(key)).lower() in (name, str(value))
                                      for p in profiles)
    recorded_depth = max([int(p.get("depth") or 0) for p in profiles] + [10])
    qos = QoSProfile(depth=depth or recorded_depth)
    if profiles and not all_are("reliability", "reliable", 1):
        qos.reliability = ReliabilityPolicy.BEST_EFFORT
    if all_are("durability", "transient_local", 1):
        qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
    return qos


class Player:
    """Publishes a bag's messages (raw CDR) with their recorded timing scaled by 1/rate.

    ``step()`` publishes the next message at once; ``play_all(realtime=True)`` waits on
    the monotonic clock until each message's due time ``(t - t_first) / rate`` after the
    start, in slices of at most ``slice_s`` so that ``stop_event`` is honoured promptly.
    With ``clock=True`` a rosgraph_msgs/Clock with the bag time is published on /clock
    before each message and at every wait slice, and a /clock recorded in the bag is *not*
    republished (one clock: the player's, which follows the log times, the rate and the
    loop; for a bag recorded with sim time as log time it has the recorded values).
    ``loop`` restarts at the end, the first message of the next pass following the last one
    without a gap. A bag whose topics mix sim-time and wall-clock log times is refused
    (playing it would wait for decades): select the topics of one time base.
    """

    def __init__(self, node, path, rate: float = 1.0, topics=None, loop: bool = False,
                 clock: bool = False, qos_depth: int | None = None, slice_s: float = 0.025):
        if not rate > 0:
            raise BagError(f"play {path}: rate must be > 0, got {rate}")
        self.node, self.path, self.rate, self.loop = node, Path(path), float(rate), loop
        self.topics = None if topics is None else list(topics)
        self.slice_s = slice_s
        self._messages, channels, stamps = [], {}, {}
        self.skipped_clock = 0  # recorded /clock messages not replayed (``clock``)
        for topic, type_str, t_ns, data, meta in iter_raw(self.path, self.topics):
            if clock and topic == "/clock":  # the player publishes its own /clock
                self.skipped_clock += 1
                continue
            self._messages.append((topic, t_ns, data))
            stamps.setdefault(topic, []).append(t_ns)
            channels.setdefault(topic, (type_str, meta.get("offered_qos_profiles")))
        if not self._messages:
            raise BagError(f"play {path}: no messages on {self.topics or 'any topic'}")
        mixed = _mixed_time_bases(stamps)
        if mixed:
            raise BagError(f"play {path}: {mixed}; select the topics of one time base "
                           "with --topics")
        self._messages.sort(key=lambda m: m[1])
        self.publishers = {topic: node.create_publisher(
            get_message(type_str), topic, _playback_qos(offered, qos_depth))
            for topic, (type_str, offered) in channels.items()}
        self._clock_pub = None
        if clock:
            from rosgraph_msgs.msg import Clock
            self._clock_pub = node.create_publisher(Clock, "/clock", 10)
        self._index = 0
        self.published = 0
        self.t_first_ns = self._messages[0][1]
        self.bag_span_ns = self._messages[-1][1] - self.t_first_ns
        self._pass = 0

    def _bag_time(self, index: int, passes: int) -> int:
        """Elapsed bag time (ns since the first message) of a message in a given pass."""
        return passes * self.bag_span_ns + self._messages[index][1] - self.t_first_ns

    def publish_clock(self, t_ns: int) -> None:
        """Publish /clock = ``t_ns`` (bag time) when clock publication is on."""
        if self._clock_pub is not None:
            from rosgraph_msgs.msg import Clock
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(int(t_ns), 1_000_000_000)
            self._clock_pub.publish(msg)

    def step(self):
        """Publish the next message now; returns (topic, t_ns) or None when done."""
        if self._index >= len(self._messages):
            if not self.loop:
                return None
            self._index, self._pass = 0, self._pass + 1
        topic, t_ns, data = self._messages[self._index]
        self.publish_clock(t_ns)
        self.publishers[topic].publish(data)
        self._index += 1
        self.published += 1
        return topic, t_ns

    def play_all(self, realtime: bool = True, stop_event=None) -> int:
        """Publish to the end (forever with ``loop`` until ``stop_event``); returns count."""
        start = time.monotonic()
        base = self._bag_time(min(self._index, len(self._messages) - 1), self._pass)
        count = 0
        while stop_event is None or not stop_event.is_set():
            if realtime:
                index, passes = self._index, self._pass
                if index >= len(self._messages):
                    if not self.loop:
                        break
                    index, passes = 0, passes + 1
                due = start + (self._bag_time(index, passes) - base) * 1e-9 / self.rate
                while (now := time.monotonic()) < due:
                    if stop_event is not None and stop_event.is_set():
                        return count
                    time.sleep(min(self.slice_s, due - now))
                    ahead_s = max(0.0, due - time.monotonic()) * self.rate
                    self.publish_clock(self._messages[index][1] - int(ahead_s * 1e9))
            if self.step() is None:
                break
            count += 1
        return count

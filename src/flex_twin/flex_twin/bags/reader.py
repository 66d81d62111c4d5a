"""Reading bags, independent of the writer, and surviving damage.

:class:`_FileScan` walks the ``.mcap`` record by record with the ``mcap`` library's record
classes, checks chunk CRCs (``mcap.stream_reader.get_chunk_data_stream``), skips damaged
byte ranges up to the next intact chunk and reindexes a file without footer/summary or
metadata.yaml (as ``ros2 bag reindex``). What was lost is named in one
:class:`BagDamageWarning` line (byte and log-time ranges, message counts against
metadata.yaml or the MCAP statistics); a bag with nothing readable raises
:class:`BagError` (one line, rc 2 in the CLI). rclpy deserializes the CDR bytes.

Time bases: a bag has one; ``bag info`` warns about a bag that mixes sim-time and
wall-clock log times (:func:`mixed_time_bases`) and ``play`` refuses it.
"""
from __future__ import annotations

from pathlib import Path

from .message_types import BagError, get_message


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


def bag_metadata(path: Path, problems: list | None = None) -> dict | None:
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
        self.meta = bag_metadata(path, problems)
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
    mixed = mixed_time_bases(stamps)
    if mixed:
        warnings_.append(f"bag {path}: {mixed}")
    return {"path": str(path), "version": meta.get("version"),
            "storage_identifier": meta.get("storage_identifier", "mcap"),
            "duration_s": (end - start) * 1e-9, "start_time_s": start * 1e-9,
            "end_time_s": end * 1e-9, "message_count": sum(t["count"] for t in topics),
            "topics": topics, "warnings": warnings_}


SIM_TIME_LIMIT_NS = 10**9 * 86400 * 365 * 10  # log times below 10 years: not the wall clock


def mixed_time_bases(stamps: dict) -> str | None:
    """A sentence when some topics' log times are sim time (from ~0) and others wall-clock
    time (since 1970), else None."""
    sim = sorted(t for t, ts in stamps.items() if ts and max(ts) < SIM_TIME_LIMIT_NS)
    wall = sorted(t for t, ts in stamps.items() if ts and min(ts) >= SIM_TIME_LIMIT_NS)
    if sim and wall:
        return (f"mixed time bases: log times of {', '.join(sim)} are sim time (from 0), "
                f"of {', '.join(wall)} wall-clock time (recorded without --use-sim-time?)")
    return None

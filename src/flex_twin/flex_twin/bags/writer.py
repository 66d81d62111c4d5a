"""Writing bags through the ``rosbags`` library (``rosbags.rosbag2.Writer``, format version
9, MCAP storage): ``metadata.yaml`` as Jazzy's rosbag2 writes it, MCAP schemas with encoding
``ros2msg`` and the RIHS01 type hash, and the channel metadata ``offered_qos_profiles`` that
rosbag2 needs to replay with the recorded QoS. Only the standard message packages of
:data:`~.message_types.STANDARD_PACKAGES` are accepted.

Crash safety: rosbags' MCAP storage writer is subclassed to write each chunk's CRC32 and to
flush each closed chunk to the file; :class:`BagWriter` closes a chunk every 0.5 s (besides
rosbags' 1 MiB limit), so a killed recorder keeps all but the last ~0.5 s.
"""
from __future__ import annotations

import threading
import time
from pathlib import Path

from .message_types import (BagError, exact_cdr, qos_to_rosbags, get_message, jazzy_typestore,
                            type_string)


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

    def add_topic(self, name: str, msg_type_str: str, qos=None, type_hash: str | None = None,
                  installed: bool = True):
        """Declare a topic; ``qos`` is a ``QoSProfile`` or a list of them (offered QoS);
        ``installed=False``: a type known to the Jazzy typestore only (tf2_msgs: not in
        the pip wheels), written as CDR bytes."""
        from rclpy.qos import QoSProfile
        if installed:
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
                offered_qos_profiles=[qos_to_rosbags(q) for q in profiles])
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
            data = exact_cdr(serialize_message(msg_or_bytes), type_string(msg_or_bytes))
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

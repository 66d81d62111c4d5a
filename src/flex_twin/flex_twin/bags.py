"""rosbag2 (MCAP) bags for flex-twin: write, read, summarise, record and play.

Writing goes through the ``rosbags`` library (``rosbags.rosbag2.Writer``, format version 9,
MCAP storage): it writes ``metadata.yaml`` as Jazzy's rosbag2 does, MCAP schemas with
encoding ``ros2msg`` and the RIHS01 type hash, and the channel metadata
``offered_qos_profiles`` that rosbag2 needs to replay with the recorded QoS. Message
definitions come from the rosbags Jazzy typestore, so only the standard message packages
in :data:`STANDARD_PACKAGES` are accepted.

Reading is independent of the writer: the ``mcap`` library (Foxglove's reader) iterates the
``.mcap`` files and rclpy deserializes the CDR bytes. ``rosidl_runtime_py`` is not in the
pip wheels, so :func:`get_message` resolves ``pkg/msg/Name`` with importlib as it does.

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


def _mcap_files(path: Path) -> list[Path]:
    """The bag's .mcap files: metadata.yaml's ``relative_file_paths``, else ``*.mcap``."""
    if not path.is_dir():
        raise BagError(f"bag {path}: no such directory")
    meta = _metadata(path)
    if meta is not None:
        if meta.get("storage_identifier") != "mcap":
            raise BagError(f"bag {path}: storage_identifier "
                           f"{meta.get('storage_identifier')!r}, only 'mcap' is supported")
        files = [path / f for f in meta.get("relative_file_paths", [])]
    else:
        files = sorted(path.glob("*.mcap"))
    if not files or not all(f.is_file() for f in files):
        raise BagError(f"bag {path}: no readable .mcap file (looked for {files or '*.mcap'})")
    return files


def _metadata(path: Path) -> dict | None:
    """``rosbag2_bagfile_information`` of ``path/metadata.yaml`` or None when absent."""
    import yaml
    meta_path = Path(path) / "metadata.yaml"
    if not meta_path.is_file():
        return None
    with open(meta_path, encoding="utf8") as f:
        return (yaml.safe_load(f) or {}).get("rosbag2_bagfile_information", {})


def iter_raw(path, topics=None):
    """(topic, type_str, t_ns, cdr_bytes, channel_metadata) in log-time order per file."""
    from mcap.reader import make_reader
    files = _mcap_files(Path(path))
    wanted = None if topics is None else set(topics)
    if wanted is not None:
        missing = wanted - set(topic_types(path))
        if missing:
            raise BagError(f"bag {path}: no topic(s) {sorted(missing)}")
    for file in files:
        with open(file, "rb") as stream:
            for schema, channel, message in make_reader(stream).iter_messages(
                    topics=None if wanted is None else sorted(wanted)):
                if channel.message_encoding != "cdr" or schema is None:
                    raise BagError(f"bag {file}: topic {channel.topic} has encoding "
                                   f"{channel.message_encoding!r}, expected 'cdr'")
                yield (channel.topic, schema.name, message.log_time, bytes(message.data),
                       channel.metadata)


def topic_types(path) -> dict[str, str]:
    """``{topic: type_str}`` of every channel in the bag's MCAP summaries."""
    from mcap.reader import make_reader
    out = {}
    for file in _mcap_files(Path(path)):
        with open(file, "rb") as stream:
            summary = make_reader(stream).get_summary()
        if summary is None:
            raise BagError(f"bag {file}: MCAP file has no summary (not closed cleanly)")
        for channel in summary.channels.values():
            out[channel.topic] = summary.schemas[channel.schema_id].name
    return out


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
    messages), i.e. the mean rate between its first and last message.
    """
    path = Path(path)
    stamps = {name: [] for name in topic_types(path)}
    for topic, _type, t_ns, _data, _meta in iter_raw(path):
        stamps[topic].append(t_ns)
    every = [t for ts in stamps.values() for t in ts]
    start, end = (min(every), max(every)) if every else (0, 0)
    meta = _metadata(path) or {}
    topics = []
    for name, type_str in sorted(topic_types(path).items()):
        ts, span = stamps[name], max(stamps[name] or [0]) - min(stamps[name] or [0])
        topics.append({"name": name, "type": type_str, "count": len(ts),
                       "frequency_hz": (len(ts) - 1) / (span * 1e-9) if span else None})
    return {"path": str(path), "version": meta.get("version"),
            "storage_identifier": meta.get("storage_identifier", "mcap"),
            "duration_s": (end - start) * 1e-9, "start_time_s": start * 1e-9,
            "end_time_s": end * 1e-9, "message_count": sum(t["count"] for t in topics),
            "topics": topics}


class BagWriter:
    """A new rosbag2 bag (format version 9) written with ``rosbags``; thread-safe.

    Use as a context manager: the bag is closed (MCAP summary and metadata.yaml written)
    on leaving the block, also on an exception or KeyboardInterrupt, so that a stopped
    recording remains a complete bag. ``close()`` is idempotent.
    """

    def __init__(self, path, *, storage: str = "mcap"):
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
        self._writer.open()
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
    (waiting up to ``discovery_timeout_s``). Each message is stamped with the node clock at
    the callback (the receive time, as rosbag2; ``use_sim_time`` applies), or with its
    ``header.stamp`` for topics in ``use_header_stamp``. The subscription is RELIABLE
    unless a publisher offers BEST_EFFORT, TRANSIENT_LOCAL when all publishers offer it.
    """

    def __init__(self, node, bag_writer: BagWriter, topics, *, use_header_stamp=(),
                 depth: int = 100, discovery_timeout_s: float = 5.0):
        self.node, self.writer, self.depth = node, bag_writer, depth
        self.use_header_stamp = set(use_header_stamp)
        self._subs = {}
        self.add_topics(dict(topics) if isinstance(topics, dict) else discover_types(
            node, list(topics), discovery_timeout_s))

    def add_topics(self, types: dict[str, str]) -> list[str]:
        """Subscribe ``{name: type}`` topics not yet recorded; returns the new names."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        new = [n for n in types if n not in self._subs]
        for name in new:
            cls = get_message(types[name])
            offered = [i.qos_profile for i in self.node.get_publishers_info_by_topic(name)]
            qos = QoSProfile(depth=self.depth)
            if any(q.reliability == ReliabilityPolicy.BEST_EFFORT for q in offered):
                qos.reliability = ReliabilityPolicy.BEST_EFFORT
            if offered and all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL
                               for q in offered):
                qos.durability = DurabilityPolicy.TRANSIENT_LOCAL
            self.writer.add_topic(name, types[name], qos=offered or [qos])
            self._subs[name] = self.node.create_subscription(
                cls, name, self._callback(name, cls), qos, raw=True)
        return new

    def _callback(self, name, cls):
        from rclpy.serialization import deserialize_message
        by_header = name in self.use_header_stamp

        def callback(data):
            if by_header:
                stamp = deserialize_message(data, cls).header.stamp
                t_ns = stamp.sec * 1_000_000_000 + stamp.nanosec
            else:
                t_ns = self.node.get_clock().now().nanoseconds
            if not self.writer.closed:
                self.writer.write(name, data, t_ns)
        return callback

    def stop(self) -> None:
        """Destroy the subscriptions (the writer stays open; the caller closes it)."""
        for sub in self._subs.values():
            self.node.destroy_subscription(sub)
        self._subs = {}


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
    before each message and at every wait slice. ``loop`` restarts at the end, the first
    message of the next pass following the last one without a gap.
    """

    def __init__(self, node, path, rate: float = 1.0, topics=None, loop: bool = False,
                 clock: bool = False, qos_depth: int | None = None, slice_s: float = 0.025):
        if not rate > 0:
            raise BagError(f"play {path}: rate must be > 0, got {rate}")
        self.node, self.path, self.rate, self.loop = node, Path(path), float(rate), loop
        self.topics = None if topics is None else list(topics)
        self.slice_s = slice_s
        self._messages, channels = [], {}
        for topic, type_str, t_ns, data, meta in iter_raw(self.path, self.topics):
            self._messages.append((topic, t_ns, data))
            channels.setdefault(topic, (type_str, meta.get("offered_qos_profiles")))
        if not self._messages:
            raise BagError(f"play {path}: no messages on {self.topics or 'any topic'}")
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

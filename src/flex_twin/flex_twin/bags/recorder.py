"""Recording topics into a bag (``flex-twin record``).

The log time is the receive time (wall clock, as rosbag2) or, with ``use_sim_time``
(``record --use-sim-time``, the default when /clock is published or recorded; the twin
demo), the latest /clock. rclpy is imported lazily.
"""
from __future__ import annotations

import bisect
import struct
import time

from .message_types import BagError, get_message
from .writer import BagWriter

#: the key of the recorder's own /clock subscription among the recorded topics' names
CLOCK = "\0clock"
#: use_sim_time: messages published in the last HOLD_NS (their source timestamps, this
#: host's clock) wait for a later callback, so that one delivered late (another topic's
#: reader, a reliable resend) is still handled in publication order; at most HOLD_MAX
HOLD_NS, HOLD_MAX = 50_000_000, 10000


def leading_stamp_ns(data) -> int:
    """The first field of a serialized message whose first field is a
    builtin_interfaces/Time or a std_msgs/Header (its stamp): CDR after the 4-byte
    encapsulation header (byte 1 odd: little endian), int32 sec, uint32 nanosec; in ns.
    No deserialization (the recorder's per-message cost, :func:`starts_with_stamp`)."""
    sec, nanosec = struct.unpack_from("<iI" if data[1] & 1 else ">iI", data, 4)
    return sec * 1_000_000_000 + nanosec


def starts_with_stamp(cls) -> bool:
    """Whether the message class's first field is a Header or a Time (then
    :func:`leading_stamp_ns` reads header.stamp, or that time, from its bytes)."""
    kind = cls.SLOT_TYPES[0] if cls.SLOT_TYPES else None
    name = (tuple(getattr(kind, "namespaces", ())), getattr(kind, "name", None))
    return name in ((("std_msgs", "msg"), "Header"), (("builtin_interfaces", "msg"), "Time"))


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

    Each callback takes every message waiting in all the subscriptions and handles them in
    the order they were published (:meth:`_take`), with ``depth`` (1000) per topic: a
    lockstep suite publishing faster than one executor wake-up per message loses none.
    :meth:`drain` does the same without the executor. ``keep``: topics whose serialized
    messages are also kept in :attr:`kept` (the twin demo's summary reads them).
    """

    def __init__(self, node, bag_writer: BagWriter, topics, *, use_header_stamp=(),
                 depth: int = 1000, discovery_timeout_s: float = 5.0,
                 use_sim_time: bool = False, keep=()):
        from rclpy.clock import Clock, ClockType
        self.node, self.writer, self.depth = node, bag_writer, depth
        #: the serialized messages of the topics in ``keep``, as recorded (in order)
        self.kept = {name: [] for name in keep}
        self.use_header_stamp = set(use_header_stamp)
        self.use_sim_time = use_sim_time
        self._subs, self._pending, self._types, self._classes = {}, {}, {}, {}
        self._sim_ns = None   # the latest /clock (use_sim_time)
        self._early = []      # (name, data, receive ns) before the first /clock
        self._held = []       # (source ns, name, data) published after the latest /clock
        self._clock_sub = None
        if use_sim_time:
            from rclpy.qos import QoSProfile, ReliabilityPolicy
            from rosgraph_msgs.msg import Clock as ClockMsg
            # BEST_EFFORT, VOLATILE: compatible with every /clock publisher
            self._clock_sub = node.create_subscription(
                ClockMsg, "/clock", lambda data, info: self._take(CLOCK, data, info),
                QoSProfile(depth=depth, reliability=ReliabilityPolicy.BEST_EFFORT),
                raw=True)
        self._timer = node.create_timer(0.1, self._poll,
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

    def _on_clock(self, data) -> None:
        t_ns = leading_stamp_ns(data)  # Clock: its one field
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
        self._classes[name] = cls
        return lambda data, info: self._take(name, data, info)

    def _take(self, name, data, info) -> None:
        """The executor's message, then every message waiting in the subscriptions, in the
        order they were published (source timestamps): with ``use_sim_time`` each gets
        the /clock published last before it (those published in the last HOLD_NS wait for
        the next callback, the 0.1 s timer or :meth:`stop`); one wake-up of the executor
        per message could not keep up with a lockstep suite (its messages beyond a
        subscription's depth were lost)."""
        self._drain([(info["source_timestamp"], name, data)])

    def drain(self) -> None:
        """Take and record every message waiting in the subscriptions now (what a
        callback does; the twin demo calls it after each step instead of waking the
        executor per message); those published in the last HOLD_NS may wait (class
        docstring)."""
        self._drain()

    def _drain(self, batch=()) -> None:
        batch = self._held + list(batch)
        subs = list(self._subs.items())
        if self._clock_sub is not None:
            subs.append((CLOCK, self._clock_sub))
        for key, sub in subs:
            with sub.handle:
                while (got := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                    batch.append((got[1]["source_timestamp"], key, got[0]))
        batch.sort(key=lambda b: b[0])
        self._held = []
        if self.use_sim_time and len(batch) <= HOLD_MAX:  # late deliveries: sorted in
            cut = bisect.bisect_right([b[0] for b in batch], time.time_ns() - HOLD_NS)
            batch, self._held = batch[:cut], batch[cut:]
        self._handle(batch)

    def _poll(self) -> None:
        """The 0.1 s steady timer: new publishers, held messages."""
        self._subscribe_pending()
        if self._held:
            self._drain()

    def _handle(self, batch) -> None:
        for _, key, msg in batch:
            if key == CLOCK:
                self._on_clock(msg)
            else:
                self._write(key, msg)

    def _write(self, name, data) -> None:
        """Write one serialized message with its log time (class docstring)."""
        if name in self.kept:
            self.kept[name].append(data)
        if name in self.use_header_stamp or (self.use_sim_time and name == "/clock"):
            t_ns = self._stamp_ns(name, data)
        elif self.use_sim_time:
            if self._sim_ns is None:  # stamped with the first /clock when it comes
                self._early.append((name, data, self.node.get_clock().now().nanoseconds))
                return
            t_ns = self._sim_ns
        else:
            t_ns = self.node.get_clock().now().nanoseconds
        if not self.writer.closed:
            self.writer.write(name, data, t_ns)

    def _stamp_ns(self, name, data) -> int:
        """header.stamp (or a Clock's time) of a serialized message, in ns: read from the
        bytes where the type starts with it (:func:`starts_with_stamp`), else from the
        deserialized message's header."""
        cls = self._classes[name]
        if starts_with_stamp(cls):
            return leading_stamp_ns(data)
        from rclpy.serialization import deserialize_message
        stamp = deserialize_message(data, cls).header.stamp
        return stamp.sec * 1_000_000_000 + stamp.nanosec

    def stop(self) -> None:
        """Destroy the subscriptions and declare topics that never had a publisher (the
        writer stays open; the caller closes it). Messages held for the first /clock are
        written with their receive time when no /clock came."""
        held, self._held = self._held, []
        self._handle(held)  # with the latest /clock
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

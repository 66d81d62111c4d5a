"""Playing a bag back on its topics (``flex-twin play``), with the recorded QoS.

rclpy is imported lazily.
"""
from __future__ import annotations

import time
from pathlib import Path

from .message_types import BagError, get_message
from .reader import mixed_time_bases, iter_raw


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
        mixed = mixed_time_bases(stamps)
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

"""``flex-twin record | play | bag info``: rosbag2 (MCAP) bags without the ``ros2 bag`` CLI.

rclpy is imported inside the command functions only: the caller (flex-twin's main, or
:func:`main` here) sets ``ROS_AUTOMATIC_DISCOVERY_RANGE`` and ``ROS_DOMAIN_ID`` first.
Each command uses its own rclpy context (no rclpy signal handlers): SIGINT and SIGTERM set
a stop flag, and the bag is closed in ``finally``, so Ctrl-C leaves a complete bag; SIGKILL
or a crash leaves every chunk closed so far (chunks are closed every 0.5 s), which
``bag info``, ``play`` and ``read_bag`` reindex. Damage found in a bag is printed as one
``flex-twin: warning:`` line; an unreadable bag is one ``flex-twin: error:`` line, rc 2.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

from flex_model.ros import ros_environment
from flex_model.command import stop_on_signals


@contextmanager
def _ros_node(name: str):
    """An rclpy context, a node and a SingleThreadedExecutor; a stop flag set by
    SIGINT/SIGTERM (handlers restored and ROS shut down on exit)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    ctx = rclpy.Context()
    ros_environment()   # LOCALHOST discovery before the participant exists
    rclpy.init(context=ctx)
    node = executor = None
    try:
        with stop_on_signals() as stop:
            node = rclpy.create_node(name, context=ctx)
            executor = SingleThreadedExecutor(context=ctx)
            executor.add_node(node)
            yield node, executor, stop
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def standard_topics(node) -> dict[str, str]:
    """``{topic: type}`` of the graph's topics with one type from a standard package."""
    from .bags import STANDARD_PACKAGES
    return {name: types[0] for name, types in node.get_topic_names_and_types()
            if len(types) == 1 and types[0].split("/")[0] in STANDARD_PACKAGES}


def _topic_specs(specs):
    """``NAME`` or ``NAME=pkg/msg/Type`` -> (names without type, {name: type})."""
    names, typed = [], {}
    for spec in specs:
        name, _, type_str = spec.partition("=")
        if type_str:
            typed[name] = type_str
        else:
            names.append(name)
    return names, typed


def _clock_published(node, executor, stop, wait_s: float) -> bool:
    """Whether /clock has a publisher, watching the graph up to ``wait_s`` (a node's
    publishers appear one by one)."""
    deadline = time.monotonic() + wait_s
    while not node.get_publishers_info_by_topic("/clock"):
        if time.monotonic() > deadline or stop.is_set():
            return False
        executor.spin_once(timeout_sec=0.05)
    return True


def cmd_record(args) -> int:
    """Record topics into a new bag until Ctrl-C/SIGTERM or ``--duration``."""
    from .bags import BagError, BagWriter, Recorder, discover_types, get_message
    if not args.topics and not args.all:
        raise BagError("record: give topic names or --all")
    out = Path(args.output) if args.output else (
        Path("runs") / f"{datetime.now():%Y%m%d-%H%M%S}" / "bag")
    if args.duration is not None and not args.duration > 0:
        raise BagError(f"record: --duration must be > 0 s, got {args.duration}")
    with _ros_node("flex_twin_recorder") as (node, executor, stop):
        names, types = _topic_specs(args.topics)
        if args.all:  # watch the graph for a while; new topics are added while recording
            deadline = time.monotonic() + args.discovery_time
            while time.monotonic() < deadline and not stop.is_set():
                executor.spin_once(timeout_sec=0.05)
            types.update({n: t for n, t in standard_topics(node).items() if n not in types})
        types.update(discover_types(node, names, args.discovery_timeout, stop))
        for type_str in types.values():
            get_message(type_str)  # refuse unknown types before creating the bag
        sim_time = getattr(args, "use_sim_time", None)
        if sim_time is None:  # /clock recorded or published (a lockstep suite): its time
            sim_time = "/clock" in types or _clock_published(node, executor, stop,
                                                             args.discovery_time)
        writer = BagWriter(out)
        recorder = None
        try:
            recorder = Recorder(node, writer, types, use_header_stamp=args.use_header_stamp,
                                use_sim_time=sim_time)
            base = "sim time (/clock)" if sim_time else "receive time"
            print(f"recording {len(types)} topic(s) to {out}: {', '.join(sorted(types))}; "
                  f"log time = {base}", file=sys.stderr, flush=True)
            t_end = None if args.duration is None else time.monotonic() + args.duration
            next_scan = time.monotonic() + 0.5
            while not stop.is_set() and (t_end is None or time.monotonic() < t_end):
                executor.spin_once(timeout_sec=0.05)
                writer.flush_if_due()  # a killed recorder keeps all but the last ~0.5 s
                if args.all and time.monotonic() > next_scan:
                    next_scan = time.monotonic() + 0.5
                    for name in recorder.add_topics(standard_topics(node)):
                        print(f"recording new topic {name}", file=sys.stderr, flush=True)
        finally:
            try:
                if recorder is not None:
                    recorder.stop()  # also declares topics that never had a publisher
            finally:
                writer.close()
    counts = writer.counts
    print(f"recorded {sum(counts.values())} message(s) on {len(counts)} topic(s) to {out}")
    return 0


@contextmanager
def _bag_warnings():
    """Print each BagDamageWarning as one line on stderr (``flex-twin: warning: ...``)."""
    import warnings

    from .bags import BagDamageWarning

    def show(message, category, *_args, **_kwargs):
        print(f"flex-twin: warning: {message}", file=sys.stderr, flush=True)
    with warnings.catch_warnings():
        warnings.simplefilter("always", BagDamageWarning)
        warnings.showwarning = show
        yield


def cmd_play(args) -> int:
    """Publish a bag's messages with their recorded timing (scaled by 1/--rate)."""
    from .bags import BagError, Player
    if not args.rate > 0:
        raise BagError(f"play: --rate must be > 0, got {args.rate}")
    with _ros_node("flex_twin_player") as (node, executor, stop), _bag_warnings():
        player = Player(node, args.path, rate=args.rate, topics=args.topics or None,
                        loop=args.loop, clock=args.clock)
        if player.skipped_clock:
            print(f"flex-twin: note: /clock is the player's (bag log time); the "
                  f"{player.skipped_clock} recorded /clock message(s) are not replayed",
                  file=sys.stderr, flush=True)
        deadline = time.monotonic() + args.delay  # let subscribers discover the publishers
        while time.monotonic() < deadline and not stop.is_set():
            executor.spin_once(timeout_sec=0.02)
        t0 = time.monotonic()
        count = player.play_all(realtime=True, stop_event=stop)
        wall = time.monotonic() - t0
    print(f"published {count} message(s) from {args.path} in {wall:.3f} s")
    return 0


def cmd_bag_info(args) -> int:
    """Print a bag's summary (``--json``: machine-readable, units in the key names)."""
    import warnings

    from .bags import BagDamageWarning, bag_info
    with warnings.catch_warnings():  # bag_info lists them in info["warnings"]
        warnings.simplefilter("ignore", BagDamageWarning)
        info = bag_info(args.path)
    for text in info["warnings"]:
        print(f"flex-twin: warning: {text}", file=sys.stderr, flush=True)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0

    def stamp(t_s):
        return f"{datetime.fromtimestamp(t_s):%Y-%m-%d %H:%M:%S.%f} ({t_s:.9f} s)"
    version = "no metadata.yaml" if info["version"] is None else f"v{info['version']}"
    print(f"bag:       {info['path']} (rosbag2 {version}, {info['storage_identifier']})")
    print(f"duration:  {info['duration_s']:.6f} s")
    print(f"start:     {stamp(info['start_time_s'])}")
    print(f"end:       {stamp(info['end_time_s'])}")
    print(f"messages:  {info['message_count']}")
    width = max([len(t["name"]) for t in info["topics"]] + [5])
    for t in info["topics"]:
        freq = "-" if t["frequency_hz"] is None else f"{t['frequency_hz']:.3f} Hz"
        print(f"  {t['name']:<{width}}  {t['type']:<40} {t['count']:>8}  {freq}")
    return 0


def add_bag_parsers(subparsers) -> None:
    """Add ``record``, ``play`` and ``bag info`` to an argparse subparsers object."""
    sp = subparsers.add_parser("record", help="record topics into a rosbag2 (MCAP) bag")
    sp.add_argument("topics", nargs="*", metavar="TOPIC",
                    help="topic name, or NAME=pkg/msg/Type to skip type discovery")
    sp.add_argument("--all", action="store_true",
                    help="every topic of a standard message type seen on the graph")
    sp.add_argument("--output", "-o", help="new bag directory "
                    "(default runs/<timestamp>/bag)")
    sp.add_argument("--duration", type=float, help="stop after S seconds")
    sp.add_argument("--use-header-stamp", nargs="+", default=(), metavar="TOPIC",
                    help="stamp these topics with header.stamp instead of receive time")
    sim = sp.add_mutually_exclusive_group()
    sim.add_argument("--use-sim-time", dest="use_sim_time", action="store_true",
                     default=None, help="log time = the latest /clock (default when /clock "
                     "is published or among the recorded topics)")
    sim.add_argument("--no-sim-time", dest="use_sim_time", action="store_false",
                     help="log time = wall-clock receive time even when /clock is published")
    sp.add_argument("--discovery-time", type=float, default=0.5,
                    help="--all: seconds to watch the graph before the first subscriptions "
                    "(topics seen later are added every 0.5 s while recording)")
    sp.add_argument("--discovery-timeout", type=float, default=5.0,
                    help="seconds to wait for named topics to appear")
    sp.set_defaults(func=cmd_record)

    sp = subparsers.add_parser("play", help="publish a bag with its recorded timing")
    sp.add_argument("path", help="bag directory")
    sp.add_argument("--rate", type=float, default=1.0, help="time scale factor (2 = 2x)")
    sp.add_argument("--topics", nargs="+", help="only these topics")
    sp.add_argument("--loop", action="store_true", help="restart at the end (until Ctrl-C)")
    sp.add_argument("--clock", action="store_true", help="publish /clock with the bag "
                    "time (a /clock recorded in the bag is then not replayed)")
    sp.add_argument("--delay", type=float, default=0.5,
                    help="seconds to wait for discovery before the first message")
    sp.set_defaults(func=cmd_play)

    sp = subparsers.add_parser("bag", help="bag tools")
    bag_sub = sp.add_subparsers(dest="bag_command", required=True)
    sp = bag_sub.add_parser("info", help="duration, start/end and per-topic counts, rates")
    sp.add_argument("path", help="bag directory")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_bag_info)


def main(argv=None) -> int:
    """``python -m flex_twin.bag_cli record|play|bag info`` (same as in flex-twin)."""
    parser = argparse.ArgumentParser(prog="flex-twin")
    add_bag_parsers(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    # flex_model.command.run_command's exit codes (0, 2 + one line for bad input) without
    # importing it: it loads flex_model.simulate (numba, ~1.2 s of the recorder's start)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"flex-twin: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

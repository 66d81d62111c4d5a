"""rosbag2 (MCAP) bags for flex-twin: write, read, summarise, record and play.

One module per job: :mod:`.message_types` (the standard message packages, typestore, QoS and
CDR conversions), :mod:`.writer` (:class:`BagWriter`, crash-safe MCAP through ``rosbags``),
:mod:`.reader` (damage-tolerant reading, :func:`read_bag`, :func:`bag_info`),
:mod:`.recorder` (:class:`Recorder`) and :mod:`.player` (:class:`Player`).
Times are integer nanoseconds (``t_ns``) in the bag; summaries are in seconds (``_s``).
rclpy is imported lazily (inside functions) so that importing this package never starts ROS.
"""
from .message_types import STANDARD_PACKAGES, BagError, get_message, jazzy_typestore, type_string
from .player import Player
from .reader import BagDamageWarning, bag_info, iter_raw, read_bag, topic_types
from .recorder import Recorder, discover_types
from .writer import BagWriter

__all__ = ["STANDARD_PACKAGES", "BagDamageWarning", "BagError", "BagWriter", "Player",
           "Recorder", "bag_info", "discover_types", "get_message", "iter_raw",
           "jazzy_typestore", "read_bag", "topic_types", "type_string"]

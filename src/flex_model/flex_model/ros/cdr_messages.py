"""Messages of a fixed layout serialized from a template (CDR), published as bytes.

rclpy's ``Publisher.publish`` takes a serialized message (``bytes``) as well as a message
object. A message whose strings and array lengths never change (the model node's
JointState of n joints, PoseStamped, Clock, Imu, the shape's MarkerArray) has its bytes
at fixed offsets, so it is serialized once here and every publication only writes the
header stamps and the float64 fields into that buffer: no Python message objects filled,
no conversion to C structs, no serialization by rclpy (with a subscriber present the
conversion path cost 80-90 us of wall time per JointState against 30 us for bytes on the
dev machine; docs/benchmarks.md, in-loop section).

The encoding is the plain CDR (XCDR1, little endian) of ROS 2's rmw_fastrtps: a 4-byte
encapsulation header ``00 01 00 00``, then every field in declaration order, each
primitive aligned to its size (at most 8) counted from the end of that header; strings
as uint32 length (with the NUL) and the bytes; sequences as uint32 count and the
elements. The padding bytes are zero, as in what a subscriber receives when rclpy
publishes the message object, so equal messages give equal bytes, those bytes
(src/flex_model/test/test_cdr_messages.py). (rclpy's ``serialize_message`` leaves the
padding as it was in memory and may end with 4 bytes more per empty float64[]: its size
estimate aligns one as if it had items; the wire does not carry them.)
Building a template walks the message in Python (about 6 us a field: once, at start).
"""
from __future__ import annotations

import re
import struct

import numpy as np
from rosidl_parser import definition as idl

#: the encapsulation header of little-endian plain CDR (what rmw_fastrtps writes)
ENCAPSULATION = b"\x00\x01\x00\x00"

_BASIC = {  # rosidl basic type -> (struct code, size)
    "boolean": ("?", 1), "octet": ("B", 1), "char": ("B", 1), "uint8": ("B", 1),
    "int8": ("b", 1), "uint16": ("H", 2), "int16": ("h", 2), "uint32": ("I", 4),
    "int32": ("i", 4), "uint64": ("Q", 8), "int64": ("q", 8), "float": ("f", 4),
    "double": ("d", 8), "long double": ("d", 8), "wchar": ("H", 2)}


_CUTS = re.compile(r"[.\[]")  # where a field path's parents end


class _Encoder:
    """Plain CDR of a message object; records the offset of every primitive field by its
    path (``header.stamp.sec``, ``position[1]``, ``markers[2].points[0].x``) and which
    bytes are padding."""

    def __init__(self):
        self.out = bytearray(ENCAPSULATION)
        self.offsets: dict[str, tuple[int, str]] = {}
        self.padding: list[int] = []

    def _align(self, size: int) -> None:
        pad = (-(len(self.out) - len(ENCAPSULATION))) % min(size, 8)
        self.padding.extend(range(len(self.out), len(self.out) + pad))
        self.out.extend(b"\x00" * pad)

    def _basic(self, typename: str, value, path: str) -> None:
        code, size = _BASIC[typename]
        self._align(size)
        if isinstance(value, bytes):  # octet / char fields come as one-byte bytes
            value = value[0]
        self.offsets[path] = (len(self.out), typename)
        self.out.extend(struct.pack("<" + code, value))

    def _string(self, value: str) -> None:
        data = value.encode("utf-8") + b"\x00"
        self._basic("uint32", len(data), "")
        self.out.extend(data)

    def _value(self, kind, value, path: str) -> None:
        if isinstance(kind, idl.BasicType):
            self._basic(kind.typename, value, path)
        elif isinstance(kind, idl.AbstractString):
            if isinstance(kind, idl.AbstractWString):
                raise TypeError(f"{path}: wstring fields are not supported")
            self._string(value)
        elif isinstance(kind, idl.NamespacedType):
            self.message(value, path + ".")
        elif isinstance(kind, idl.AbstractNestedType):
            if isinstance(kind, idl.AbstractSequence):
                self._basic("uint32", len(value), "")
            for k, item in enumerate(value):
                self._value(kind.value_type, item, f"{path}[{k}]")
        else:
            raise TypeError(f"{path}: field type {type(kind).__name__} not supported")

    def message(self, msg, prefix: str = "") -> None:
        for slot, kind in zip(msg.__slots__, msg.SLOT_TYPES):
            self._value(kind, getattr(msg, slot), prefix + slot.lstrip("_"))
        self.offsets.pop("", None)  # lengths are not addressable


def encode(msg) -> bytes:
    """The plain CDR of a message object, padding zero (equal messages, equal bytes)."""
    enc = _Encoder()
    enc.message(msg)
    return bytes(enc.out)


def padding_mask(msg) -> np.ndarray:
    """A bool array over the serialized bytes of ``msg``: True where CDR puts padding."""
    enc = _Encoder()
    enc.message(msg)
    mask = np.zeros(len(enc.out), bool)
    mask[enc.padding] = True
    return mask


class CdrTemplate:
    """A message serialized once (:func:`encode`), then re-stamped and refilled in place.

    ``stamps``: paths of builtin_interfaces/Time fields, all set to the time of each
    :meth:`fill` (``header.stamp``, ``clock``, ``markers[3].header.stamp``); ``doubles``:
    paths of float64 fields or float64 fields' parents, expanded in declaration order
    (``position`` is every element of the array, ``pose.position`` its x, y, z,
    ``markers[0].points`` every coordinate of every point), the order of the values
    :meth:`fill` takes. Everything else keeps the value ``msg`` has now.
    """

    def __init__(self, msg, stamps=(), doubles=()):
        enc = _Encoder()
        enc.message(msg)
        self.buf = np.frombuffer(enc.out, dtype=np.uint8)  # shares enc.out (a bytearray)
        sec, nsec, f8 = [], [], []
        for path in stamps:
            sec.append(self._one(enc, path + ".sec", "int32"))
            nsec.append(self._one(enc, path + ".nanosec", "uint32"))
        found = {path: [] for path in doubles}  # one pass: each field under its path
        for name, (off, kind) in enc.offsets.items():
            if kind != "double":
                continue
            for cut in [m.start() for m in _CUTS.finditer(name)] + [len(name)]:
                if name[:cut] in found:
                    found[name[:cut]].append(off)
                    break
        for path in doubles:
            if not found[path]:
                raise ValueError(f"{type(msg).__name__}: no float64 field at {path!r}")
            f8.extend(found[path])
        self.size = len(f8)
        base = len(ENCAPSULATION)  # float64s are 8-aligned from here: one view holds all
        self._f8 = np.frombuffer(enc.out, dtype="<f8", offset=base,
                                 count=(len(enc.out) - base) // 8)
        self._f8_index = np.asarray([(off - base) // 8 for off in f8], dtype=np.intp)
        self._i4 = np.frombuffer(enc.out, dtype="<i4", count=len(enc.out) // 4)
        self._u4 = np.frombuffer(enc.out, dtype="<u4", count=len(enc.out) // 4)
        self._sec = np.asarray([off // 4 for off in sec], dtype=np.intp)
        self._nsec = np.asarray([off // 4 for off in nsec], dtype=np.intp)
        self._raw = enc.out

    @staticmethod
    def _one(enc: _Encoder, path: str, kind: str) -> int:
        off, got = enc.offsets.get(path, (None, None))
        if got != kind:
            raise ValueError(f"no {kind} field at {path!r}")
        return off

    def fill(self, t: float | None = None, values=None) -> bytes:
        """The message with every stamp at the simulation time ``t`` (s, rounded to the
        nanosecond as :func:`flex_model.ros.conversions.set_time`) and the float64
        fields set to ``values`` (in the order of ``doubles``), serialized."""
        if t is not None and self._sec.size:
            sec, nsec = divmod(int(round(t * 1e9)), 1_000_000_000)
            self._i4[self._sec] = sec
            self._u4[self._nsec] = nsec
        if values is not None:
            self._f8[self._f8_index] = values
        return bytes(self._raw)


def _aligned(pos: int, size: int) -> int:
    """``pos`` moved up to a multiple of ``size`` counted from the encapsulation header's
    end (plain CDR alignment)."""
    return pos + (-(pos - len(ENCAPSULATION))) % size


def read_joint_state(data):
    """(stamp s, name bytes, name count, position, velocity, effort) of a serialized
    sensor_msgs/JointState (plain little-endian CDR, what a raw subscription takes), without
    rclpy's message objects (a third of rclpy's deserialization time): the arrays are
    float64 views of ``data``; ``name bytes`` is the serialized name list (a cache key;
    :func:`read_joint_state_names` decodes it). Raises ValueError on a malformed or
    big-endian message."""
    return _read_joint_state(data, False)


def read_joint_state_names(data) -> list[str]:
    """The joint names of a serialized sensor_msgs/JointState (:func:`read_joint_state`)."""
    return _read_joint_state(data, True)[2]


def _read_joint_state(data, decode_names: bool):
    if bytes(data[:2]) != ENCAPSULATION[:2]:
        raise ValueError("not a little-endian plain-CDR message")
    try:
        sec, nsec, frame_len = struct.unpack_from("<iII", data, 4)
        pos = _aligned(16 + frame_len, 4)
        (count,) = struct.unpack_from("<I", data, pos)
        pos += 4
        start, names = pos, [] if decode_names else None
        for _ in range(count):
            pos = _aligned(pos, 4)
            (length,) = struct.unpack_from("<I", data, pos)
            if decode_names:
                names.append(bytes(data[pos + 4:pos + 3 + length]).decode())
            pos += 4 + length
        key = bytes(data[start:pos])
        arrays = []
        for _ in range(3):
            pos = _aligned(pos, 4)
            (k,) = struct.unpack_from("<I", data, pos)
            pos = _aligned(pos + 4, 8) if k else pos + 4
            arrays.append(np.frombuffer(data, "<f8", k, pos))
            pos += 8 * k
    except (struct.error, ValueError, UnicodeDecodeError) as exc:
        raise ValueError(f"a malformed JointState ({len(data)} bytes: {exc})") from None
    return (sec + 1e-9 * nsec, key, names if decode_names else count, *arrays)

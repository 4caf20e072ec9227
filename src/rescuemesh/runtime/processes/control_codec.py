"""The control plane's encoding: msgpack with a closed schema, no pickle.

Owns: which types may cross the control plane (a fixed registry of dataclasses and enums, numpy
arrays of a few dtypes, plain msgpack values), how each is written, and the checks a decoded value
passes before anything uses it: every dataclass field against its annotation, every array against
the dtype allow-list and the size limits. Decoding constructs only registered types, through their
own constructors (whose own checks run), and resolves no names. Must not know: Zenoh, what the
calls mean, keys (runtime/processes/control.py authenticates the bytes before they get here).

docs/processes.md lists the types and the wire form of each.
"""

from __future__ import annotations

import dataclasses
import enum
import types
import typing
from collections import Counter, deque
from pathlib import PurePath

import msgpack
import numpy as np

__all__ = ["CodecError", "MAX_ARRAY_BYTES", "MAX_MESSAGE_BYTES", "decode", "encode", "registered_types"]

#: The largest control message (a set-up carries the occupancy grid: 4000 x 4000 cells at most).
MAX_MESSAGE_BYTES = 20 << 20
#: The largest array one message may carry, in bytes, and its largest number of dimensions.
MAX_ARRAY_BYTES = 16 << 20
MAX_ARRAY_DIMS = 3
#: Array dtypes that may cross (numpy's `dtype.str`): numbers and booleans, nothing with objects.
ARRAY_DTYPES = frozenset({"|b1", "|u1", "|i1", "<u2", "<i2", "<u4", "<i4", "<u8", "<i8", "<f4", "<f8"})

# msgpack extension type codes. A record is a msgpack array whose first item is its class's tag (an
# extension holding the class name), then its fields; a tuple is an array that opens with the tuple
# tag. So a whole message packs and unpacks in one msgpack call, nested records included.
_EXT_ARRAY, _EXT_ENUM, _EXT_RECORD_TAG, _EXT_TUPLE_TAG = 1, 3, 5, 6


class CodecError(ValueError):
    """Bytes that are not a valid control message, or a value that may not be sent."""


def _registry() -> tuple[dict[str, type], dict[str, type]]:
    """The closed set of dataclasses and enums, by name (imported here, once)."""
    from rescuemesh.body import LaserScan, RobotKind
    from rescuemesh.geometry import Pose2D
    from rescuemesh.maps.grid import OccupancyGrid
    from rescuemesh.mesh.config import MeshConfig
    from rescuemesh.mesh.neighbours import NeighbourInfo
    from rescuemesh.mesh.node import Transmission
    from rescuemesh.mesh.stats import MeshStats
    from rescuemesh.protocol import messages as m
    from rescuemesh.protocol.endpoint import EndpointStats
    from rescuemesh.robot.behaviours import Waypoint
    from rescuemesh.robot.policy import Rank
    from rescuemesh.robot.events import EVENT_TYPES
    from rescuemesh.robot.records import BrainConfig, FinishedBehaviour, LinkLossPolicy, OutgoingCommand
    from rescuemesh.runtime.config import RadioKind, SimConfig
    from rescuemesh.runtime.processes import control_messages as c

    records = [Pose2D, LaserScan, OccupancyGrid, MeshConfig, NeighbourInfo, Transmission, MeshStats, EndpointStats,
               Waypoint, BrainConfig, *EVENT_TYPES.values(), FinishedBehaviour, OutgoingCommand, SimConfig, m.Pose,
               m.Follow, m.ShowCam, m.ShowScan, m.LandOnTop, m.Goto, m.Stop, m.Return, m.MoveAround,
               *c.MESSAGES]
    enums = [RobotKind, RadioKind, Rank, LinkLossPolicy, m.MessageType, m.ResultCode, m.Reason, m.Capability, m.DataKind,
             *c.ENUMS]
    return {cls.__name__: cls for cls in records}, {cls.__name__: cls for cls in enums}


_RECORDS: dict[str, type] = {}
_ENUMS: dict[str, type] = {}
#: class -> ((field, the types that pass its check as they are, its check), ...): most decoded values
#: are of a type that passes outright (a float field's float), the others go through the check
_FIELDS: dict[type, tuple[tuple[str, frozenset, typing.Callable], ...]] = {}
_NAMES: dict[type, tuple[str, ...]] = {}  # a registered class -> its fields' names, in order
_TAG_OF: dict[type, msgpack.ExtType] = {}  # a registered class -> the extension that opens its array
#: (enum class, member) -> its extension, once made (by class too: IntEnum members of two enums with
#: the same value are equal, and hash alike)
_ENUM_EXT: dict[tuple[type, enum.Enum], msgpack.ExtType] = {}
_TUPLE_EXT = msgpack.ExtType(_EXT_TUPLE_TAG, b"")


class _Tag:
    """What a record's or a tuple's opening extension decodes to, until its array is complete."""

    __slots__ = ("cls",)

    def __init__(self, cls: type | None) -> None:
        self.cls = cls  # None: a tuple


_TAGS: dict[bytes, _Tag] = {}  # a registered class's name (UTF-8) -> its tag
_TUPLE = _Tag(None)
_ENUM_VALUES: dict[bytes, enum.Enum] = {}  # an enum extension's bytes -> the member, once decoded


def _load() -> None:
    if _RECORDS:
        return
    records, enums = _registry()
    for name, cls in records.items():
        hints = typing.get_type_hints(cls)
        _FIELDS[cls] = tuple((f.name, _passing(hints[f.name]), _checker(hints[f.name]))
                             for f in dataclasses.fields(cls) if f.init)
        _NAMES[cls] = tuple(field[0] for field in _FIELDS[cls])
        _TAG_OF[cls] = msgpack.ExtType(_EXT_RECORD_TAG, name.encode())
        _TAGS[name.encode()] = _Tag(cls)
    _ENUMS.update(enums)
    _RECORDS.update(records)


def registered_types() -> tuple[list[str], list[str]]:
    """The dataclasses and the enums that may cross, by name (docs/processes.md lists them)."""
    _load()
    return sorted(_RECORDS), sorted(_ENUMS)


# --- encoding ----------------------------------------------------------------------------------


def _default(value):
    cls = type(value)
    names = _NAMES.get(cls)
    if names is not None:  # a registered record (most of what crosses): its tag, then its fields in order
        return [_TAG_OF[cls], *[getattr(value, f) for f in names]]
    if cls is tuple:
        return [_TUPLE_EXT, *value]
    if isinstance(value, enum.Enum):
        ext = _ENUM_EXT.get((cls, value))
        if ext is None:
            name = cls.__name__
            if _ENUMS.get(name) is not cls:
                raise CodecError(f"enum {name} may not cross the control plane")
            ext = _ENUM_EXT[cls, value] = msgpack.ExtType(_EXT_ENUM, _pack([name, value.value]))
        return ext
    if isinstance(value, np.ndarray):
        array = np.ascontiguousarray(value)
        if array.dtype.str not in ARRAY_DTYPES or array.ndim > MAX_ARRAY_DIMS or array.nbytes > MAX_ARRAY_BYTES:
            raise CodecError(f"array {array.dtype.str} {array.shape} may not cross the control plane")
        return msgpack.ExtType(_EXT_ARRAY, _pack([array.dtype.str, list(array.shape), array.tobytes()]))
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        return [_TUPLE_EXT, *value]
    if isinstance(value, (deque, frozenset, set)):
        return list(value)
    if isinstance(value, dict):  # Counter, OrderedDict, defaultdict: as a plain dict
        return dict(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        raise CodecError(f"{cls.__name__} may not cross the control plane")
    raise CodecError(f"{type(value).__name__} may not cross the control plane")


def _pack(value) -> bytes:
    return msgpack.packb(value, default=_default, use_bin_type=True, strict_types=True)


def encode(value) -> bytes:
    """The bytes of `value`, which holds only plain values and registered types. CodecError otherwise."""
    _load()
    try:
        data = _pack(value)
    except CodecError:
        raise
    except (TypeError, ValueError, OverflowError) as error:
        raise CodecError(f"cannot encode a control message: {error}") from None
    if len(data) > MAX_MESSAGE_BYTES:
        raise CodecError(f"control message of {len(data)} bytes is over the {MAX_MESSAGE_BYTES}-byte limit")
    return data


# --- decoding ----------------------------------------------------------------------------------


class _Decoding:
    """One message's decoding: msgpack calls `ext` for each extension and `array` for each array once
    its items are decoded (innermost first). A tag is only valid as the first item of an array; the
    tags made and the tags used are counted, so a tag anywhere else (a map's value, the message
    itself, an array's second item) makes the message invalid."""

    __slots__ = ("open_tags",)

    def __init__(self) -> None:
        self.open_tags = 0

    def ext(self, code: int, data: bytes):
        if code == _EXT_RECORD_TAG:
            tag = _TAGS.get(data)
            if tag is None:
                raise CodecError(f"unknown record type {data[:40]!r}")
            self.open_tags += 1
            return tag
        if code == _EXT_TUPLE_TAG:
            if data:
                raise CodecError("malformed tuple tag")
            self.open_tags += 1
            return _TUPLE
        if code == _EXT_ENUM:
            member = _ENUM_VALUES.get(data)
            if member is None:
                member = _enum(msgpack.unpackb(data, raw=False, use_list=True))
                if len(_ENUM_VALUES) < 4096:
                    _ENUM_VALUES[bytes(data)] = member
            return member
        if code == _EXT_ARRAY:
            return _array(msgpack.unpackb(data, raw=False, use_list=True))
        raise CodecError(f"unknown extension type {code}")

    def array(self, items: list):
        if not items or type(items[0]) is not _Tag:
            return items
        self.open_tags -= 1
        cls = items[0].cls
        if cls is None:
            return tuple(items[1:])
        return _record(cls, items)


def _enum(item):
    if not (isinstance(item, list) and len(item) == 2 and isinstance(item[0], str)):
        raise CodecError("malformed enum")
    cls = _ENUMS.get(item[0])
    if cls is None:
        raise CodecError(f"unknown enum {item[0][:40]!r}")
    try:
        return cls(item[1])
    except (ValueError, TypeError):
        raise CodecError(f"{item[1]!r} is not a {cls.__name__}") from None


def _array(item) -> np.ndarray:
    if not (isinstance(item, list) and len(item) == 3 and isinstance(item[0], str) and isinstance(item[1], list)
            and isinstance(item[2], bytes)):
        raise CodecError("malformed array")
    dtype, shape, raw = item
    if dtype not in ARRAY_DTYPES:
        raise CodecError(f"array dtype {dtype[:20]!r} is not allowed")
    if len(shape) > MAX_ARRAY_DIMS or not all(type(n) is int and 0 <= n <= MAX_ARRAY_BYTES for n in shape):
        raise CodecError("array shape out of limits")
    size = np.dtype(dtype).itemsize
    for n in shape:
        size *= n
    if size != len(raw) or size > MAX_ARRAY_BYTES:
        raise CodecError(f"array of {len(raw)} bytes does not match {dtype} {shape} (limit {MAX_ARRAY_BYTES})")
    return np.frombuffer(raw, dtype=dtype).reshape(shape).copy()


def _record(cls: type, items: list):
    """An instance of registered class `cls` from its array (its tag, then its fields)."""
    fields = _FIELDS[cls]
    if len(items) - 1 != len(fields):
        raise CodecError(f"{cls.__name__} takes {len(fields)} fields, got {len(items) - 1}")
    values = items[1:]
    for (name, passing, check), value in zip(fields, values):
        if type(value) not in passing and not check(value):
            raise CodecError(f"{cls.__name__}.{name}: {type(value).__name__} does not match its type")
    try:
        return cls(*values)
    except Exception as error:  # the class's own checks (__post_init__) refused it
        raise CodecError(f"{cls.__name__} refused its fields: {type(error).__name__}: {str(error)[:120]}") from None


def _any(value) -> bool:
    return True


def _passing(hint) -> frozenset:
    """The types whose every value passes `_checker(hint)` (an empty set where each value must be
    looked at: lists, dicts, tuples, anything)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is typing.Union or origin is types.UnionType:
        return frozenset().union(*(_passing(h) for h in args))
    if hint is type(None):
        return frozenset({type(None)})
    if hint is float:
        return frozenset({float, int})
    if hint in (int, bool, str, bytes):
        return frozenset({hint})
    if origin is None and isinstance(hint, type) and not issubclass(hint, PurePath):
        if issubclass(hint, enum.Enum) or dataclasses.is_dataclass(hint):
            return frozenset({hint})  # exactly this class (a registered subclass goes through isinstance)
    return frozenset()


def _checker(hint):
    """A test of whether a decoded value matches a field annotation, compiled once per field (the
    decoded forms: lists for lists and deques, dicts, tuples, registered records and enums, arrays)."""
    if hint is typing.Any or hint is object:
        return _any
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is typing.Union or origin is types.UnionType:
        options = tuple(_checker(h) for h in args)
        return lambda v: any(check(v) for check in options)
    if hint is type(None):
        return lambda v: v is None
    if hint is float:
        return lambda v: type(v) is float or type(v) is int
    if hint is int:  # a registered IntEnum (a message type, say) is an int too
        return lambda v: type(v) is int or isinstance(v, (enum.IntEnum, enum.IntFlag))
    if hint in (bool, str, bytes):
        return lambda v: type(v) is hint
    if origin is None and isinstance(hint, type):
        if issubclass(hint, PurePath):
            return lambda v: type(v) is str
        if issubclass(hint, (enum.Enum, np.ndarray)) or dataclasses.is_dataclass(hint):
            return lambda v: isinstance(v, hint)
        if hint in (dict, Counter):
            return lambda v: type(v) is dict
        if hint in (list, deque, set, frozenset):
            return lambda v: type(v) is list
        if hint is tuple:
            return lambda v: type(v) is tuple
        raise TypeError(f"no control-plane check for {hint!r}")
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            item = _checker(args[0])
            return lambda v: type(v) is tuple and all(item(x) for x in v)
        items = tuple(_checker(h) for h in args)
        return lambda v: type(v) is tuple and len(v) == len(items) and all(c(x) for c, x in zip(items, v))
    if origin in (list, deque, set, frozenset):
        item = _checker(args[0]) if args else _any
        return lambda v: type(v) is list and all(item(x) for x in v)
    if origin in (dict, Counter):
        key, value = (_checker(args[0]), _checker(int if origin is Counter else args[1])) if args else (_any, _any)
        return lambda v: type(v) is dict and all(key(k) and value(x) for k, x in v.items())
    raise TypeError(f"no control-plane check for {hint!r}")


def decode(data: bytes):
    """The value in `data`, or CodecError (and nothing else) for anything that is not a valid message."""
    _load()
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise CodecError("a control message is bytes")
    if len(data) > MAX_MESSAGE_BYTES:
        raise CodecError(f"control message of {len(data)} bytes is over the {MAX_MESSAGE_BYTES}-byte limit")
    decoding = _Decoding()
    try:
        value = msgpack.unpackb(bytes(data), ext_hook=decoding.ext, list_hook=decoding.array, raw=False,
                                strict_map_key=False, use_list=True)
    except CodecError:
        raise
    except RecursionError:
        raise CodecError("control message nested too deep") from None
    except Exception as error:  # msgpack's own: truncated, extra data, bad types, stack limit
        raise CodecError(f"undecodable control message ({type(error).__name__}: {str(error)[:120]})") from None
    if decoding.open_tags:
        raise CodecError("a record or tuple tag that does not open an array")
    return value

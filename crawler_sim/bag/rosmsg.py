"""ROS 2 message types with or without ROS: field lists, empty messages, CDR in and out.

A bag is a file format (MCAP holding CDR), not a ROS process, so the bag layer needs the
message *layouts*, not rclpy. Each type is served by one of two backends:

* **rclpy**, when the type's Python message class and ``rclpy.serialization`` import (a Jazzy
  install, the ``ros`` extra): the classes sim_node publishes, their field lists and
  ``serialize_message`` / ``deserialize_message``. This is the ROS path, unchanged.
* otherwise **rosbags' Jazzy typestore** (a runtime dependency, public API): the same
  definitions (``typestore.fielddefs``), its message dataclasses and its CDR
  ``serialize_cdr`` / ``deserialize_cdr``.

The CDR of one message is the same in both (the wire format is the standard's), padding bytes
aside: Fast CDR leaves them uninitialised, rosbags writes zeros, and the package's encoder
(:class:`crawler_sim.bag.cdr.Encoder`, which both the node and offline recording use) zeroes
them. ``test_bag_dependencies`` checks the field lists, the empty messages and the bytes of
both backends against each other, and records and reads bags with every ROS module blocked.
"""
from __future__ import annotations

from functools import lru_cache
import importlib
from typing import Any

import numpy as np

from .errors import BagError
from .schema import canonical_type, split_type, typestore as _typestore

#: rosbags' base type names -> rclpy's (IDL) names, as ``get_fields_and_field_types`` spells them
_IDL = {'bool': 'boolean', 'byte': 'octet', 'char': 'uint8', 'float32': 'float',
        'float64': 'double'}
#: rosbags' base type names -> numpy dtypes (for empty and fixed-size arrays)
_DTYPE = {'bool': np.bool_, 'byte': np.uint8, 'char': np.uint8, 'int8': np.int8,
          'uint8': np.uint8, 'int16': np.int16, 'uint16': np.uint16, 'int32': np.int32,
          'uint32': np.uint32, 'int64': np.int64, 'uint64': np.uint64,
          'float32': np.float32, 'float64': np.float64}
#: the non-zero default values of the .msg files of the types the package records (rosbags'
#: typestore keeps no defaults; test_bag_dependencies compares every recorded type's empty
#: message with rclpy's, so a type added without its defaults here fails there)
DEFAULTS = {'geometry_msgs/msg/Quaternion': {'w': 1.0}}
# rosbags' Nodetype values (its public enum: BASE 1, NAME 2, ARRAY 3, SEQUENCE 4)
_BASE, _NAME, _ARRAY, _SEQUENCE = 1, 2, 3, 4


@lru_cache(maxsize=None)
def ros_class(type_name: str) -> type | None:
    """The rclpy message class of ``type_name``, or None when rclpy or the message package is
    not installed (then the typestore serves the type)."""
    pkg, namespace, name = split_type(type_name)
    try:
        importlib.import_module('rclpy.serialization')
        return getattr(importlib.import_module(f'{pkg}.{namespace}'), name)
    except (ImportError, AttributeError):
        return None


def _store_def(type_name: str) -> list:
    store = _typestore()
    canonical = canonical_type(type_name)
    if store is None or canonical not in store.fielddefs:
        pkg = split_type(type_name)[0]
        raise BagError(f'message type {canonical} is unknown: the Python package {pkg} is not '
                       'installed and rosbags\' Jazzy typestore does not define it')
    return store.fielddefs[canonical][1]


def _idl(node: tuple) -> str:
    """rclpy's spelling of one rosbags field type (``sequence<double>``, ``double[36]``)."""
    kind, detail = node
    if kind == _BASE:
        base, bound = detail
        if base == 'string':
            return f'string<{bound}>' if bound else 'string'
        return _IDL.get(base, base)
    if kind == _NAME:
        pkg, _, name = detail.split('/')
        return f'{pkg}/{name}'
    item, size = detail
    if kind == _ARRAY:
        return f'{_idl(item)}[{size}]'
    return f'sequence<{_idl(item)}, {size}>' if size else f'sequence<{_idl(item)}>'


@lru_cache(maxsize=None)
def field_types(type_name: str) -> dict[str, str]:
    """``{field: type}`` of ``type_name`` in rclpy's spelling (``get_fields_and_field_types``:
    ``'sequence<double>'``, ``'std_msgs/Header'``, ``'double[36]'``), from the rclpy class or
    from the typestore; :class:`BagError` for a type neither knows."""
    cls = ros_class(type_name)
    if cls is not None:
        return dict(cls.get_fields_and_field_types())
    return store_field_types(type_name)


def store_field_types(type_name: str) -> dict[str, str]:
    """:func:`field_types` from the typestore alone (what a process without ROS uses)."""
    return {name: _idl(node) for name, node in _store_def(type_name)}


def _empty(node: tuple) -> Any:
    kind, detail = node
    if kind == _BASE:
        base = detail[0]
        return '' if base == 'string' else _DTYPE[base](0).item()
    if kind == _NAME:
        return store_new(detail)
    item, size = detail
    if item[0] == _BASE and item[1][0] != 'string':
        return np.zeros(size if kind == _ARRAY else 0, dtype=_DTYPE[item[1][0]])
    return [_empty(item) for _ in range(size)] if kind == _ARRAY else []


def store_new(type_name: str) -> Any:
    """An empty message of ``type_name`` from the typestore alone (see :func:`new`): zeros,
    empty strings and sequences, and the .msg defaults of :data:`DEFAULTS`."""
    canonical = canonical_type(type_name)
    values = {name: _empty(node) for name, node in _store_def(canonical)}
    values.update(DEFAULTS.get(canonical, {}))
    return _typestore().types[canonical](**values)


def new(type_name: str) -> Any:
    """An empty message of ``type_name`` (zeros, empty strings and sequences): an instance of
    the rclpy class, or of the typestore's dataclass without ROS. Fields are set as attributes
    in both; numeric sequences take :func:`numbers`."""
    cls = ros_class(type_name)
    return cls() if cls is not None else store_new(type_name)


def numbers(type_name: str, values: Any, dtype: Any) -> Any:
    """A numeric sequence for a field of a ``type_name`` message: ``array.array`` for rclpy
    (assigned without per-element checks), a numpy array for the typestore's serialiser."""
    arr = np.ascontiguousarray(values, dtype=dtype).reshape(-1)
    if ros_class(type_name) is None:
        return arr
    from array import array
    out = array(arr.dtype.char)
    out.frombytes(arr.tobytes())
    return out


def serialize(msg: Any, type_name: str) -> bytes:
    """CDR bytes (with the encapsulation header) of ``msg``, a message of either backend."""
    msgtype = getattr(msg, '__msgtype__', None)
    if msgtype is not None:            # a typestore dataclass
        return bytes(_typestore().serialize_cdr(msg, msgtype))
    from rclpy.serialization import serialize_message
    return serialize_message(msg)


def deserialize(data: bytes, type_name: str) -> Any:
    """The message in CDR ``data`` of ``type_name`` (rclpy's class, or the typestore's
    dataclass: attributes of the same names; numeric sequences as arrays)."""
    cls = ros_class(type_name)
    if cls is not None:
        from rclpy.serialization import deserialize_message
        return deserialize_message(data, cls)
    _store_def(type_name)
    return _typestore().deserialize_cdr(bytes(data), canonical_type(type_name))


def backend(type_name: str) -> str:
    """``'rclpy'`` or ``'typestore'``: which backend serves ``type_name`` here."""
    return 'rclpy' if ros_class(type_name) is not None else 'typestore'


__all__ = ['backend', 'deserialize', 'field_types', 'new', 'numbers', 'ros_class', 'serialize',
           'store_field_types', 'store_new']

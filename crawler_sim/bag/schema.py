"""Message definitions, type hashes and QoS strings, built the way rosbag2 (Jazzy) builds them.

* :func:`full_text` concatenates the installed ``share/<pkg>/msg/<Type>.msg`` files like
  ``rosbag2_cpp::LocalMessageDefinitionSource::get_full_text``: the root file verbatim, then for
  every dependency (depth first, sorted within each file, each type once) ``"\\n"``, a line of 80
  ``=``, ``"MSG: <dep as written>"`` and the dependency's text.
* :func:`type_hash` reads the ``RIHS01_`` hash from ``share/<pkg>/msg/<Type>.json``.
* :func:`qos_profiles` / :func:`qos_yaml` give the version-9 ``offered_qos_profiles`` (a list of
  maps with string enums), as ``rosbag2_storage::serialize_rclcpp_qos_vector`` writes it.

Packages are found through ``ament_index_python``, so ``AMENT_PREFIX_PATH`` must include the prefix
that holds ``share/<pkg>`` (the venv prefix when ROS comes from PyPI wheels).
"""
from __future__ import annotations

from functools import lru_cache
import importlib
import json
from pathlib import Path
import re
from typing import Any

import yaml

from .errors import BagError

SEPARATOR = '=' * 80
# rosbag2's MSG_FIELD_TYPE_REGEX, applied to the whole file text (no multiline flag).
_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
_PRIMITIVES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string'})
_NAME = r'[a-zA-Z][a-zA-Z0-9_]*'
_TYPE_NAME = re.compile(rf'^({_NAME})/(?:({_NAME})/)?({_NAME})$')

# rmw reports infinite durations of discovered endpoints as this (RMW_DURATION_INFINITE).
INFINITE_DURATION = {'sec': 9223372036, 'nsec': 854775807}


def split_type(type_name: str) -> tuple[str, str, str]:
    """``'sensor_msgs/msg/JointState'`` or ``'sensor_msgs/JointState'`` -> (pkg, 'msg', Type)."""
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise BagError(f'invalid message type name {type_name!r} (expected pkg/msg/Type)')
    pkg, namespace, name = match.groups()
    return pkg, namespace or 'msg', name


def canonical_type(type_name: str) -> str:
    """The full ``pkg/msg/Type`` form used as schema name and topic type."""
    return '/'.join(split_type(type_name))


@lru_cache(maxsize=None)
def share_dir(pkg: str) -> Path:
    """``share/<pkg>`` of an installed ROS package, found with ``ament_index_python``."""
    from ament_index_python.packages import (
        get_package_share_directory, PackageNotFoundError)
    try:
        return Path(get_package_share_directory(pkg))
    except (PackageNotFoundError, KeyError, LookupError, ValueError) as exc:
        msg = (f'ROS package {pkg!r} not found through AMENT_PREFIX_PATH ({exc}); '
               'set AMENT_PREFIX_PATH to the prefix that holds share/{pkg}')
        raise BagError(msg) from None


def _interface_file(type_name: str, ext: str) -> Path:
    pkg, namespace, name = split_type(type_name)
    path = share_dir(pkg) / namespace / f'{name}.{ext}'
    if not path.is_file():
        raise BagError(f'no definition file {path} for {type_name}')
    return path


@lru_cache(maxsize=None)
def msg_text(type_name: str) -> str:
    """The installed ``.msg`` file of ``type_name``, verbatim."""
    return _interface_file(type_name, 'msg').read_text(encoding='utf-8')


def msg_dependencies(text: str, package: str) -> list[str]:
    """Non-primitive field types of a ``.msg`` text, as written, sorted and unique.

    A package-relative name (``MultiArrayLayout``) is qualified with ``package``.
    """
    deps = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        deps.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(deps)


@lru_cache(maxsize=None)
def full_text(type_name: str) -> str:
    """Concatenated definition of ``type_name`` and all its dependencies (rosbag2 byte layout)."""
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise BagError(f'recursion too deep resolving the definition of {type_name}')
        text = msg_text(name)
        out = [text]
        for dep in msg_dependencies(text, split_type(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out.append(f'\n{SEPARATOR}\nMSG: {dep}\n')
                out.append(append(dep, depth - 1))
        return ''.join(out)

    return append(type_name, 50)


@lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """``RIHS01_<64 hex>`` hash of ``type_name`` from its installed ``.json`` type description."""
    canonical = canonical_type(type_name)
    path = _interface_file(canonical, 'json')
    try:
        hashes = json.loads(path.read_text(encoding='utf-8'))['type_hashes']
        return next(h['hash_string'] for h in hashes if h['type_name'] == canonical)
    except (ValueError, KeyError, TypeError, StopIteration):
        raise BagError(f'no type hash for {canonical} in {path}') from None


@lru_cache(maxsize=None)
def message_class(type_name: str) -> type:
    """The rclpy message class of ``type_name`` (e.g. ``sensor_msgs.msg.JointState``)."""
    pkg, namespace, name = split_type(type_name)
    try:
        return getattr(importlib.import_module(f'{pkg}.{namespace}'), name)
    except (ImportError, AttributeError):
        raise BagError(f'message type {type_name} is not importable from Python') from None


def type_of(msg: Any) -> str:
    """``pkg/msg/Type`` of an rclpy message object (class ``sensor_msgs.msg.JointState``)."""
    cls = type(msg)
    parts = cls.__module__.split('.')
    if len(parts) < 2 or not hasattr(cls, 'get_fields_and_field_types'):
        raise BagError(f'{cls.__module__}.{cls.__qualname__} is not a ROS message class')
    return f'{parts[0]}/{parts[1]}/{cls.__name__}'


def qos_profile(*, reliability: str = 'reliable', durability: str = 'volatile',
                history: str = 'unknown', depth: int = 0) -> dict[str, Any]:
    """One offered QoS profile in the version-9 layout (string enums, infinite durations).

    The defaults are what rosbag2 records for a publisher made with ``create_publisher(T, name,
    10)``: QoS read back from discovery shows ``history: unknown, depth: 0``.
    """
    return {
        'history': history,
        'depth': int(depth),
        'reliability': reliability,
        'durability': durability,
        'deadline': dict(INFINITE_DURATION),
        'lifespan': dict(INFINITE_DURATION),
        'liveliness': 'automatic',
        'liveliness_lease_duration': dict(INFINITE_DURATION),
        'avoid_ros_namespace_conventions': False,
    }


def qos_yaml(profiles: list[dict[str, Any]]) -> str:
    """``offered_qos_profiles`` as the YAML string stored in MCAP channel metadata."""
    return yaml.safe_dump(profiles, default_flow_style=False, sort_keys=False)


def parse_qos_yaml(text: str) -> list[dict[str, Any]]:
    """Inverse of :func:`qos_yaml`; an empty or unreadable string gives ``[]``."""
    try:
        value = yaml.safe_load(text) if text else []
    except yaml.YAMLError:
        return []
    return value if isinstance(value, list) else []

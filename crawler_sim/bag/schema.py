"""Message definitions, type hashes and QoS strings, built the way rosbag2 (Jazzy) builds them.

* :func:`full_text` concatenates the installed ``share/<pkg>/msg/<Type>.msg`` files like
  ``rosbag2_cpp::LocalMessageDefinitionSource::get_full_text``: the root file verbatim, then for
  every dependency (depth first, sorted within each file, each type once) ``"\\n"``, a line of 80
  ``=``, ``"MSG: <dep as written>"`` and the dependency's text.
* :func:`type_hash` reads the ``RIHS01_`` hash from ``share/<pkg>/msg/<Type>.json``.
* :func:`qos_profiles` / :func:`qos_yaml` give the version-9 ``offered_qos_profiles`` (a list of
  maps with string enums), as ``rosbag2_storage::serialize_rclcpp_qos_vector`` writes it.

Where the definitions come from, first found wins (recording works wherever rclpy works):

1. the install prefix of the message package's own Python module: ``<prefix>/lib/pythonX.Y/
   site-packages/<pkg>`` -> ``<prefix>/share/<pkg>`` (a sourced ``/opt/ros/jazzy``, a colcon
   workspace, or the PyPI wheels in a venv); no environment variable needed;
2. the ament index (``AMENT_PREFIX_PATH``), for packages whose module lives elsewhere;
3. rosbags' built-in Jazzy typestore, which knows the definitions and type hashes of the
   standard interfaces (its text is the normalised concatenation, not the file verbatim).
"""
from __future__ import annotations

from functools import lru_cache
import importlib
import importlib.util
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


def _module_share_dir(pkg: str) -> Path | None:
    """``<prefix>/share/<pkg>`` of the prefix the Python module ``pkg`` is installed in."""
    try:
        spec = importlib.util.find_spec(pkg)
    except (ImportError, ValueError):
        return None
    origins = list(spec.submodule_search_locations or []) if spec is not None else []
    if spec is not None and spec.origin and not origins:
        origins = [str(Path(spec.origin).parent)]
    for origin in origins:
        # site-packages/<pkg> -> site-packages -> pythonX.Y -> lib -> <prefix>
        for parent in Path(origin).resolve().parents:
            candidate = parent / 'share' / pkg
            if (candidate / 'package.xml').is_file() or (candidate / 'msg').is_dir():
                return candidate
    return None


def _ament_share_dir(pkg: str) -> Path | None:
    """``share/<pkg>`` from the ament index, or None (no index, or not in it)."""
    try:
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory(pkg))
    except Exception:  # noqa: BLE001 - unset AMENT_PREFIX_PATH raises OSError, unknown pkg others
        return None


@lru_cache(maxsize=None)
def share_dir(pkg: str) -> Path | None:
    """``share/<pkg>`` of an installed ROS package (module prefix, then ament index), or None."""
    return _module_share_dir(pkg) or _ament_share_dir(pkg)


def _interface_file(type_name: str, ext: str) -> Path | None:
    pkg, namespace, name = split_type(type_name)
    share = share_dir(pkg)
    path = None if share is None else share / namespace / f'{name}.{ext}'
    return path if path is not None and path.is_file() else None


@lru_cache(maxsize=1)
def _typestore() -> Any:
    """rosbags' Jazzy typestore (None when rosbags is not installed)."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        return None
    return get_typestore(Stores.ROS2_JAZZY)


def typestore() -> Any:
    """rosbags' Jazzy typestore (public name of the cached store; None without rosbags)."""
    return _typestore()


def _not_found(type_name: str, what: str) -> BagError:
    pkg = split_type(type_name)[0]
    return BagError(
        f'no {what} for {type_name}: share/{pkg} was found neither next to the Python module '
        f'{pkg} nor through AMENT_PREFIX_PATH, and rosbags\' Jazzy typestore does not know it')


@lru_cache(maxsize=None)
def msg_text(type_name: str) -> str:
    """The installed ``.msg`` file of ``type_name``, verbatim."""
    path = _interface_file(type_name, 'msg')
    if path is None:
        raise _not_found(type_name, 'definition file')
    return path.read_text(encoding='utf-8')


def _typestore_text(type_name: str) -> str | None:
    store = _typestore()
    if store is None or type_name not in store.fielddefs:
        return None
    return store.generate_msgdef(type_name, ros_version=2)[0]


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
    """Concatenated definition of ``type_name`` and all its dependencies (rosbag2 byte layout).

    Without the installed ``.msg`` files (see the module docstring) rosbags' typestore text.
    """
    canonical = canonical_type(type_name)
    if _interface_file(canonical, 'msg') is None:
        text = _typestore_text(canonical)
        if text is None:
            raise _not_found(canonical, 'definition file')
        return text
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
    if path is None:
        store = _typestore()
        if store is not None and canonical in store.fielddefs:
            return str(store.hash_rihs01(canonical))
        raise _not_found(canonical, 'type hash')
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

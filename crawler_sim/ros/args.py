"""Command-line checks shared by the nodes: what rcl would reject with a traceback, or ignore
without a word, is reported in one line naming the argument (``main`` exits with code 2).

- ``--params-file FILE``: missing, not YAML, or not a ROS 2 parameter file (no
  ``<node>: ros__parameters:``, e.g. a scene file of ``config/scenes/``);
- arguments outside ``--ros-args``: rclpy hands them to the program, which takes none, so
  ``gait_node --params-file best_gait.yaml`` (``--ros-args`` forgotten) would otherwise play the
  default gait without a word;
- parameters given for the node that it does not declare (``-p frequncy:=1.0``), with the
  nearest declared name: rclpy ignores them silently.

``-h``/``--help`` (outside ``--ros-args``) is answered here too, before ``rclpy.init``:
``help_text`` lists a node's parameters from its parameter table (type, description, range,
default, read-only), as ``ros2 param describe`` would show them on a running node. Without it
``--help`` was refused as a stray argument, and a Jazzy user without the ros2 CLI had no way to
see the parameters short of reading the source.
"""
from __future__ import annotations

import difflib
import textwrap
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

if TYPE_CHECKING:
    from rclpy.node import Node

__all__ = ['ArgsError', 'check_args', 'check_params_files', 'help_requested', 'help_text',
           'print_help_and_exit', 'unknown_parameters']

#: parameters rclpy or the middleware declare or read on every node
_ROS_OWN = ('use_sim_time', 'start_type_description_service')


class ArgsError(ValueError):
    """A command-line argument the node cannot use."""


def _has_ros_parameters(node) -> bool:
    if not isinstance(node, dict):
        return False
    return 'ros__parameters' in node or any(_has_ros_parameters(v) for v in node.values())


def check_params_files(args: Sequence[str]) -> None:
    """Raise ArgsError for a ``--params-file`` in ``args`` that is not a ROS 2 parameter
    file."""
    import yaml
    for k, arg in enumerate(args):
        if arg != '--params-file':
            continue
        if k + 1 >= len(args):
            raise ArgsError('--params-file needs a file name')
        path = args[k + 1]
        try:
            with open(path, encoding='utf-8') as f:
                doc = yaml.safe_load(f)
        except OSError as exc:
            raise ArgsError(f'cannot read parameter file {path}: {exc.strerror}') from None
        except yaml.YAMLError as exc:
            raise ArgsError(f'{path} is not valid YAML: {exc}'.replace('\n', ' ')) from None
        if not _has_ros_parameters(doc):
            hint = ''
            if isinstance(doc, dict) and 'scene' in doc:
                hint = (' It is a scene file: run it with `crawler-sim simulate ' + path
                        + '`; the node\'s parameter files are in config/ros/ '
                        '(e.g. config/ros/crawler_sim.yaml).')
            raise ArgsError(f'{path} is not a ROS 2 parameter file (no '
                            f'"<node name>: ros__parameters:" section).{hint}')


def check_args(argv: Sequence[str], executable: str) -> None:
    """Raise ArgsError for a bad ``--params-file`` or an argument outside ``--ros-args``
    (``argv[0]`` is the program). ``executable`` names the node in the hint."""
    args = list(argv[1:])
    check_params_files(args)
    from rclpy.utilities import remove_ros_args
    try:
        stray = remove_ros_args(['prog', *args])[1:]
    except Exception as exc:  # noqa: BLE001 - rclpy's RCLInvalidROSArgsError, a traceback
        raise ArgsError(_rcl_reason(str(exc))) from None
    if not stray:
        return
    if '--params-file' in stray or '-p' in stray or '--param' in stray:
        raise ArgsError(f'{" ".join(stray)}: ROS arguments go after --ros-args, e.g. '
                        f'`ros2 run crawler_sim {executable} --ros-args --params-file FILE` '
                        f'(without --ros-args the file is not read)')
    raise ArgsError(f'unexpected argument(s) {" ".join(stray)}: {executable} takes only ROS '
                    f'arguments (after --ros-args: -p name:=value, --params-file FILE, -r ...)')


HELP_FLAGS = ('-h', '--help')


def help_requested(argv: Sequence[str]) -> bool:
    """True when ``-h`` or ``--help`` is among the program's own arguments (``argv[0]`` is the
    program; inside a ``--ros-args`` section the words belong to ROS)."""
    inside = False
    for arg in argv[1:]:
        if arg == '--ros-args':
            inside = True
        elif arg == '--' and inside:
            inside = False
        elif not inside and arg in HELP_FLAGS:
            return True
    return False


def _type_name(default: Any) -> str:
    """The parameter type ``ros2 param describe`` names for a default value (an empty list is
    a double array: the nodes' list parameters are numbers)."""
    if isinstance(default, bool):
        return 'boolean'
    if isinstance(default, int):
        return 'integer'
    if isinstance(default, float):
        return 'double'
    if isinstance(default, str):
        return 'string'
    if isinstance(default, (list, tuple)):
        if default and all(isinstance(x, str) for x in default):
            return 'string array'
        if default and all(isinstance(x, int) and not isinstance(x, bool) for x in default):
            return 'integer array'
        return 'double array'
    return 'not set' if default is None else type(default).__name__


def _value(value: Any) -> str:
    """A value as it is typed on the command line (``-p name:=VALUE``)."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, str):
        return repr(value) if value == '' else value
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_value(x) for x in value) + ']'
    if value is None:
        return '(not set)'
    return repr(value)


def help_text(executable: str, node_name: str, summary: str,
              parameters: Mapping[str, tuple]) -> str:
    """The ``--help`` text of a node: usage, ``summary`` and every parameter of its table.

    ``parameters`` maps a name to ``(default, description, range or None[, read_only])`` (the
    shape of sim_node's, gait_node's and replay_node's tables; a default of None is a
    parameter declared without a value). Each is listed as ``ros2 param describe`` lists it,
    plus its default value.
    """
    width = 100
    lines = [f'usage: {executable} [-h] [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] '
             '[-r FROM:=TO ...]]', '']
    lines += textwrap.wrap(summary, width)
    lines.append('')
    lines += textwrap.wrap(f'Parameters of node {node_name} (-p NAME:=VALUE after --ros-args, '
                           f'or a --params-file section "{node_name}: ros__parameters:"):',
                           width)
    for name, entry in parameters.items():
        default, desc, rng = entry[0], entry[1], entry[2]
        read_only = bool(entry[3]) if len(entry) > 3 else False
        lines += ['', f'Parameter name: {name}', f'  Type: {_type_name(default)}']
        lines += textwrap.wrap(f'Description: {desc}', width, initial_indent='  ',
                               subsequent_indent='    ')
        lines.append(f'  Default value: {_value(default)}')
        if rng is not None or read_only:
            lines.append('  Constraints:')
        if rng is not None:
            lines += [f'    Min value: {rng[0]:g}', f'    Max value: {rng[1]:g}']
        if read_only:
            lines.append('    Read only: true (set at start only)')
    return '\n'.join(lines) + '\n'


def print_help_and_exit(argv: Sequence[str], executable: str, node_name: str, summary: str,
                        parameters: Mapping[str, tuple]) -> None:
    """If ``argv`` asks for help, print ``help_text`` to stdout and exit with code 0 (before
    rclpy.init: no ROS context, no DDS participant for a question about the command line)."""
    if help_requested(argv):
        print(help_text(executable, node_name, summary, parameters), end='', flush=True)
        raise SystemExit(0)


def ros_sections(args: Sequence[str]) -> list[str]:
    """The arguments inside ``--ros-args`` sections (each ends at ``--`` or at the next
    ``--ros-args``), in order."""
    out: list[str] = []
    inside = False
    for arg in args:
        if arg == '--ros-args':
            inside = True
        elif arg == '--' and inside:
            inside = False
        elif inside:
            out.append(arg)
    return out


def _params_file_sections(args: Sequence[str]) -> list[tuple[str, bool, dict]]:
    """Every ``ros__parameters`` section of the ``--params-file`` files among ``args``: (its
    key path without slashes at the ends, e.g. 'ns/gait_node'; whether a key on the path
    holds a ``*``; its parameters). Unreadable files give none (check_params_files reports
    them)."""
    import yaml
    found: list[tuple[str, bool, dict]] = []

    def walk(doc: object, path: str, wild: bool) -> None:
        if not isinstance(doc, dict):
            return
        for key, value in doc.items():
            if key == 'ros__parameters' and isinstance(value, dict):
                found.append((path, wild, value))
            else:
                walk(value, f'{path}/{str(key).strip("/")}'.strip('/'), wild or '*' in str(key))
    for k, arg in enumerate(args[:-1]):
        if arg == '--params-file':
            try:
                with open(args[k + 1], encoding='utf-8') as f:
                    walk(yaml.safe_load(f), '', False)
            except (OSError, yaml.YAMLError):
                pass
    return found


def given_names(args: Sequence[str], name: str, fqn: str) -> list[str]:
    """Parameter names the arguments give the node called ``name`` (fully qualified ``fqn``):
    ``-p NAME:=VALUE`` and the ``ros__parameters`` of its sections in ``--params-file`` files
    (keyed ``name``, ``/name``, ``/ns/name`` or nested ``/ns: {name: ...}``)."""
    ros = ros_sections(args)
    names: list[str] = []
    for k, arg in enumerate(ros[:-1]):
        if arg in ('-p', '--param') and ':=' in ros[k + 1]:
            names.append(ros[k + 1].split(':=', 1)[0])
    targets = {name, fqn.lstrip('/')}
    for path, _wild, params in _params_file_sections(ros):
        if path in targets:
            names.extend(_flat(params))
    return names


def _wildcard_names(args: Sequence[str]) -> set[str]:
    """Parameter names a ``--params-file`` gives every node (under a key with ``*``, e.g.
    ``/**``): one file may serve several nodes, so a name there is not a typo for this one."""
    return {n for _path, wild, params in _params_file_sections(args) if wild
            for n in _flat(params)}


def _flat(params: dict, prefix: str = '') -> list[str]:
    out = []
    for key, value in params.items():
        name = f'{prefix}{key}'
        out.extend(_flat(value, name + '.') if isinstance(value, dict) else [name])
    return out


def _rcl_reason(text: str) -> str:
    """rcl's message on arguments it cannot parse, without its source locations."""
    text = text.split('Failed to parse ROS arguments: ', 1)[-1]
    reason = text.split('. Error:', 1)[0].split(', at /', 1)[0]
    if 'remap rule' in reason:
        reason += (' (-r FROM:=TO: names are letters, digits and _, not starting with a digit; '
                   '__ns:=/a/b for a namespace, __node:=name for the node\'s name)')
    return f'invalid ROS arguments: {reason}'


def unknown_parameters(node: Node, argv: Sequence[str]) -> list[str]:
    """One message per parameter given to ``node`` (``-p`` or a ``--params-file`` section for
    its name) that it does not declare, with the nearest declared name. Names given to every
    node (a ``/**`` section) and rclpy's own are not reported."""
    # rclpy has no public accessor for the overrides it read, so they are read from the same
    # arguments here; without this a misspelt name is ignored without a word
    given: Iterable[str] = given_names(list(argv), node.get_name(),
                                       node.get_fully_qualified_name())
    known = set(node.get_parameters_by_prefix(''))
    wild = _wildcard_names(list(argv))
    out = []
    for name in given:
        if (name in known or name in _ROS_OWN or name in wild
                or name.startswith('qos_overrides.')):
            continue
        near = difflib.get_close_matches(name, sorted(known - set(_ROS_OWN)), n=1)
        hint = f' (did you mean {near[0]}?)' if near else ''
        out.append(f'{name} is not a parameter of {node.get_name()}{hint}')
    return out

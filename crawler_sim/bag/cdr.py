"""CDR of ROS 2 messages through one layout walker: vectorized decoding, the encoder, trimming.

A recording holds hundreds of thousands of messages per topic that differ only in numbers: same
frame id, same joint names, same array lengths. :func:`decode` therefore

1. groups messages by byte length and takes the first of each group as a *template*;
2. walks the template once (:func:`layout`), following the type's field list from rclpy and the
   XCDR1 alignment rules of Fast CDR (alignment relative to the payload after the 4-byte
   encapsulation header; the items of an empty sequence are not aligned, although Fast CDR
   counts that padding in the message length when the sequence is last), and
   records where every numeric field lies and which bytes (string contents, sequence counts,
   encapsulation kind) must equal the template's;
3. checks the template's decoded values against ``rclpy.serialization.deserialize_message``;
4. checks the fixed bytes of all rows at once and slices the numeric columns out with numpy.

Rows that do not match their template (and whole groups whose template fails step 3) go through
``deserialize_message`` one by one, so the result never depends on the fast path being right.
Padding bytes are ignored: Fast CDR leaves them uninitialised.

:class:`Encoder` is the other direction, and the package's one CDR encoder: it serialises one
prototype with ``serialize_message``, walks it with the same :func:`layout`, and then makes each
message with one ``struct.pack`` of the whole message, the numbers packed between the
prototype's constant bytes (a few microseconds instead of the Python-to-C conversion of the
whole message). :func:`set_fields` returns given CDR bytes with some numeric fields set to new
values, walking the message only as far as those fields.

:class:`Trimmer` cuts Fast CDR's surplus tail off a serialisation. All of them share the layout
walker and its alignment rules, and one table of struct codes.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import re
import struct
from typing import Any, Collection, Mapping, Sequence

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from .rosmsg import deserialize, field_types, serialize

ENCAPSULATION = 4
_ROW_BYTES = 256 << 10          # bytes of message rows copied at once by Decoder.add
_PRIMITIVE = {
    'boolean': '|u1', 'octet': '|u1', 'char': '|u1', 'uint8': '|u1', 'int8': '|i1',
    'int16': '<i2', 'uint16': '<u2', 'int32': '<i4', 'uint32': '<u4', 'float': '<f4',
    'int64': '<i8', 'uint64': '<u8', 'double': '<f8',
}
_SEQUENCE = re.compile(r'^sequence<([^,>]+)(?:, *\d+)?>$')
_ARRAY = re.compile(r'^(.+)\[(\d+)\]$')
_BOUNDED_STRING = re.compile(r'^string<\d+>$')


#: struct format character of each numpy dtype string of :data:`_PRIMITIVE`
_STRUCT = {'|u1': 'B', '|i1': 'b', '<i2': 'h', '<u2': 'H', '<i4': 'i', '<u4': 'I', '<f4': 'f',
           '<i8': 'q', '<u8': 'Q', '<f8': 'd'}


class LayoutError(Exception):
    """The template cannot be walked (unsupported type or inconsistent bytes)."""


class UndecodableMessage(ValueError):
    """A message that even ``deserialize_message`` cannot read (damaged data)."""


@dataclass
class Layout:
    """Where the numeric fields of one message lie, and which bytes are fixed.

    ``fields`` maps a dotted field path (``header.stamp.sec``, ``position``) to
    ``(byte offset, element count, numpy dtype)``; ``fixed`` lists byte positions whose values
    must equal the template's for another message to share this layout.
    """

    length: int
    fields: dict[str, tuple[int, int, str]] = field(default_factory=dict)
    fixed: list[int] = field(default_factory=list)
    end: int = 0            # bytes the content really takes (<= length, see Trimmer)


class _Enough(Exception):
    """Internal: every field a partial walk looks for has been found."""


class _Walker:
    def __init__(self, data: bytes, only: frozenset[str] = frozenset()) -> None:
        self.data = data
        self.pos = ENCAPSULATION
        self.layout = Layout(len(data), fixed=[0, 1])
        self.only = only

    def align(self, size: int) -> None:
        rel = self.pos - ENCAPSULATION
        self.pos += (-rel) % size

    def take(self, size: int) -> int:
        start = self.pos
        if start + size > len(self.data):
            raise LayoutError('template shorter than its layout')
        self.pos += size
        return start

    def count(self) -> int:
        self.align(4)
        start = self.take(4)
        self.layout.fixed.extend(range(start, start + 4))
        return int.from_bytes(self.data[start:start + 4], 'little')

    def string(self) -> None:
        n = self.count()
        start = self.take(n)
        self.layout.fixed.extend(range(start, start + n))

    def numbers(self, path: str, dtype: str, n: int) -> None:
        size = np.dtype(dtype).itemsize
        if n:                      # Fast CDR does not align an empty sequence's (absent) items
            self.align(min(size, 8))
        start = self.take(size * n)
        self.layout.fields[path] = (start, n, dtype)
        if self.only and self.only <= self.layout.fields.keys():
            raise _Enough

    def element(self, path: str, type_str: str) -> None:
        if type_str in _PRIMITIVE:
            self.numbers(path, _PRIMITIVE[type_str], 1)
        elif type_str == 'string' or _BOUNDED_STRING.match(type_str):
            self.string()
        elif (match := _SEQUENCE.match(type_str)) is not None:
            self.sequence(path, match.group(1))
        elif (match := _ARRAY.match(type_str)) is not None:
            self.array(path, match.group(1), int(match.group(2)))
        elif '/' in type_str:
            self.message(path, type_str)
        else:
            raise LayoutError(f'unsupported field type {type_str!r}')

    def sequence(self, path: str, item: str) -> None:
        n = self.count()
        if item in _PRIMITIVE:
            self.numbers(path, _PRIMITIVE[item], n)
        else:
            for i in range(n):
                self.element(f'{path}.{i}', item)

    def array(self, path: str, item: str, n: int) -> None:
        if item in _PRIMITIVE:
            self.numbers(path, _PRIMITIVE[item], n)
        else:
            for i in range(n):
                self.element(f'{path}.{i}', item)

    def message(self, path: str, type_str: str) -> None:
        pkg, _, name = type_str.rpartition('/')
        for name, sub in field_types(f'{pkg.split("/")[0]}/msg/{name}').items():
            self.element(f'{path}.{name}' if path else name, sub)


def layout(data: bytes, type_name: str, *, only: Collection[str] = ()) -> Layout:
    """Layout of the CDR message ``data`` (with its encapsulation header) of ``type_name``.

    With ``only`` (dotted paths of numeric fields) the walk stops once those are found: the
    layout then describes the message up to them (``end`` is where the walk stopped), and a
    path that is not found is a :class:`LayoutError`.
    """
    if len(data) < ENCAPSULATION or data[:2] != b'\x00\x01':
        raise LayoutError('not little-endian plain CDR')
    walker = _Walker(data, frozenset(only))
    try:
        walker.message('', type_name)
    except _Enough:
        pass
    walker.layout.end = walker.pos
    missing = sorted(walker.only - walker.layout.fields.keys())
    if missing:
        raise LayoutError(f'{", ".join(missing)}: not numeric fields of {type_name}')
    return walker.layout


class Trimmer:
    """Cut the surplus bytes off rclpy's CDR serialisations of one message type.

    Fast CDR sizes a message counting the alignment of the items of empty sequences, but writes
    no such padding, so e.g. a JointTrajectory whose points have an empty ``effort`` comes out
    4 bytes per point longer than its content. ``rclpy`` ignores the tail; rosbags refuses
    messages with more than 3 surplus bytes ("CDR message size mismatch"). :meth:`trim` returns
    ``data`` cut to its content (walked with :func:`layout`), unchanged when the type cannot be
    walked. Layouts are cached per message length and reused when the bytes that fix the
    structure (sequence counts, strings) are those of the cached message, so the common case
    costs one tuple comparison.
    """

    def __init__(self, type_name: str) -> None:
        self.type_name = type_name
        self._cache: dict[int, tuple[Any, tuple, int]] = {}
        self._walkable = True

    def trim(self, data: bytes) -> bytes:
        """``data`` without its surplus tail (bytes beyond the content)."""
        if not self._walkable:
            return data
        entry = self._cache.get(len(data))
        if entry is not None:
            getter, values, end = entry
            if getter(data) == values:
                return data if end >= len(data) else data[:end]
        try:
            lay = layout(data, self.type_name)
        except LayoutError:
            return data
        except Exception:  # noqa: BLE001 - a type rclpy cannot describe: leave it as it is
            self._walkable = False
            return data
        fixed = sorted(set(lay.fixed)) or [0]
        getter = _itemgetter(fixed)
        self._cache[len(data)] = (getter, getter(data), lay.end)
        return data if lay.end >= len(data) else data[:lay.end]


def _itemgetter(positions: list[int]) -> Any:
    from operator import itemgetter
    if len(positions) == 1:
        pos = positions[0]
        return lambda data: (data[pos],)
    return itemgetter(*positions)


def field_value(msg: Any, path: str) -> Any:
    """Value of dotted ``path`` in an rclpy message (``header.stamp.sec``)."""
    for part in path.split('.'):
        msg = msg[int(part)] if part.isdigit() else getattr(msg, part)
    return msg


def _slow(data: bytes, type_name: str, paths: Sequence[str]) -> dict[str, NDArray]:
    """Fields ``paths`` of one message through rclpy, or rosbags without ROS
    (:func:`crawler_sim.bag.rosmsg.deserialize`; UndecodableMessage if it fails)."""
    try:
        msg = deserialize(data, type_name)
    except Exception as exc:  # noqa: BLE001 - rclpy and rosbags raise their own types
        raise UndecodableMessage(f'undecodable {type_name} message ({exc})') from None
    out = {}
    for path in paths:
        value = field_value(msg, path)
        if isinstance(value, (bytes, bytearray)):
            value = list(value)
        out[path] = np.atleast_1d(np.asarray(value))
    return out


def _template_ok(template: bytes, lay: Layout, type_name: str, paths: Sequence[str]) -> bool:
    """Check the fast layout against rclpy's own decoding of the template."""
    try:
        expected = _slow(template, type_name, paths)
    except Exception:  # noqa: BLE001 - a template rclpy cannot read is simply not fast-pathed
        return False
    row = np.frombuffer(template, dtype=np.uint8)[None, :]
    for path in paths:
        got = _columns(row, lay, path)[0]
        if got.shape != expected[path].shape or not np.array_equal(
                got, expected[path].astype(got.dtype), equal_nan=got.dtype.kind == 'f'):
            return False
    return True


def _columns(rows: NDArray[np.uint8], lay: Layout, path: str) -> NDArray:
    offset, n, dtype = lay.fields[path]
    size = np.dtype(dtype).itemsize
    block = np.ascontiguousarray(rows[:, offset:offset + size * n])
    return block.view(dtype).reshape(len(rows), n).astype(
        np.dtype(dtype).newbyteorder('='), copy=False)


@dataclass
class _Template:
    layout: Layout
    fixed: NDArray[np.int64]
    values: NDArray[np.uint8]


class Decoder:
    """Accumulate the numeric fields ``paths`` of many messages of ``type_name``, in order.

    Feed message bytes with :meth:`add` (a buffer plus per-message starts and lengths), then
    take the arrays with :meth:`columns`. Layouts are cached per message length, so the template
    walk and its rclpy cross-check run once per distinct layout.

    Attributes
    ----------
    fast, slow : int
        Messages decoded by the vectorized path and by ``deserialize_message``.
    nbytes : int
        Bytes of the decoded arrays held so far.
    """

    def __init__(self, type_name: str, paths: Sequence[str]) -> None:
        self.type_name = type_name
        self.paths = tuple(paths)
        self.fast = 0
        self.slow = 0
        self.nbytes = 0          # bytes of decoded arrays held (for callers' memory bounds)
        self._n = 0
        self._templates: dict[int, _Template | None] = {}
        self._parts: dict[str, list[tuple[NDArray[np.int64], NDArray]]] = {
            p: [] for p in self.paths}

    def __len__(self) -> int:
        return self._n

    def add(self, buffer: NDArray[np.uint8], starts: NDArray[np.int64],
            lengths: NDArray[np.int64]) -> None:
        """Decode the messages ``buffer[starts[i]:starts[i] + lengths[i]]``.

        All or nothing: if a message cannot be decoded (:class:`UndecodableMessage`), none of
        this call's messages are kept.
        """
        if len(starts) == 0:
            return
        staged: dict[str, list[tuple[NDArray[np.int64], NDArray]]] = {p: [] for p in self.paths}
        counts = [0, 0]
        uniq = np.unique(lengths)
        for length in uniq:
            sel = np.flatnonzero(lengths == length) if len(uniq) > 1 else None
            sub = starts if sel is None else starts[sel]
            pos = (np.arange(len(starts)) if sel is None else sel) + self._n
            # rows are copied (n, length) in blocks of about _ROW_BYTES, not all at once
            step = max(1, _ROW_BYTES // max(int(length), 1))
            window = sliding_window_view(buffer, int(length))
            for k in range(0, len(sub), step):
                self._add_rows(window[sub[k:k + step]], pos[k:k + step], staged, counts)
        for path in self.paths:
            self._parts[path].extend(staged[path])
            self.nbytes += sum(pos.nbytes + values.nbytes for pos, values in staged[path])
        self.fast += counts[0]
        self.slow += counts[1]
        self._n += len(starts)

    def columns(self) -> dict[str, NDArray]:
        """``{path: array of shape (N, width)}``; NaN-padded where widths differ."""
        return {p: _assemble(self._parts[p], self._n) for p in self.paths}

    def widths(self, path: str) -> NDArray[np.int64]:
        """Shape (N,): the number of values each message holds in ``path`` (a sequence's
        length), so that the NaN padding of :meth:`columns` is never mistaken for data."""
        widths = np.zeros(self._n, np.int64)
        for positions, values in self._parts[path]:
            widths[positions] = values.shape[1]
        return widths

    def _template(self, row: NDArray[np.uint8]) -> _Template | None:
        data = row.tobytes()
        try:
            lay = layout(data, self.type_name)
        except LayoutError:
            return None
        if not all(p in lay.fields for p in self.paths) or not _template_ok(
                data, lay, self.type_name, self.paths):
            return None
        fixed = np.array(lay.fixed, dtype=np.int64)
        return _Template(lay, fixed, row[fixed].copy())

    def _add_rows(self, rows: NDArray[np.uint8], positions: NDArray[np.int64],
                  staged: dict[str, list], counts: list[int]) -> None:
        length = rows.shape[1]
        if length not in self._templates:
            self._templates[length] = self._template(rows[0])
        template = self._templates[length]
        if template is not None:
            match = np.all(rows[:, template.fixed] == template.values, axis=1)
            if match.all():
                fast_rows, fast_pos, slow = rows, positions, np.zeros(0, np.int64)
            else:
                fast = np.flatnonzero(match)
                fast_rows, fast_pos, slow = rows[fast], positions[fast], np.flatnonzero(~match)
            for path in self.paths:
                staged[path].append((fast_pos, _columns(fast_rows, template.layout, path)))
            counts[0] += len(fast_pos)
        else:
            slow = np.arange(len(rows))
        for i in slow:
            values = _slow(rows[i].tobytes(), self.type_name, self.paths)
            for path in self.paths:
                staged[path].append((positions[i:i + 1], values[path][None, :]))
        counts[1] += len(slow)


def _assemble(parts: list[tuple[NDArray[np.int64], NDArray]], total: int) -> NDArray:
    if not parts:
        return np.zeros((total, 0))
    width = max(values.shape[1] for _, values in parts)
    dtypes = {values.dtype for _, values in parts}
    ragged = any(values.shape[1] != width for _, values in parts)
    dtype = np.result_type(*dtypes, np.float64) if ragged else np.result_type(*dtypes)
    if not ragged:
        positions = np.concatenate([pos for pos, _ in parts])
        if len(positions) == total and np.array_equal(positions, np.arange(total)):
            return np.concatenate([values for _, values in parts]).astype(dtype, copy=False)
    out = (np.full((total, width), np.nan, dtype=dtype) if ragged
           else np.empty((total, width), dtype))
    for positions, values in parts:
        out[positions, :values.shape[1]] = values
    return out


class Encoder:
    """CDR bytes of messages that differ from a prototype only in some numeric fields.

    Parameters
    ----------
    prototype : message
        An rclpy message, or without ROS the typestore's (:mod:`crawler_sim.bag.rosmsg`), with
        the final shape: strings, sequence lengths and every field not listed in
        ``groups`` are taken from it, for every message encoded.
    type_name : str
        ``pkg/msg/Type`` of the prototype.
    groups : sequence of sequences of dotted paths
        The numeric fields that change, in groups of fields that are adjacent in the CDR bytes
        (``('header.stamp.sec', 'header.stamp.nanosec')``, ``('position',)``), the groups in
        the order of their bytes.

    The whole message is ONE ``struct.Struct``: the prototype's bytes between the groups are
    ``s`` fields packed from constants, so a message is one ``pack`` call (no copy of a
    template, no call per group). ``encode(*values)`` takes one flat sequence of values per
    group and returns what ``rclpy.serialization.serialize_message`` returns for the prototype
    with those values, except for padding bytes, which are zero here (Fast CDR leaves them
    uninitialised). The constructor checks that packing the prototype's own values gives its
    serialisation back; it raises :class:`LayoutError` if the layout cannot be walked, a path
    is not a numeric field of the prototype, a group is not contiguous, the groups are not in
    byte order, or the check fails. Values are not checked: a wrong count raises
    ``struct.error``, a wrong number of groups ``TypeError``.

    Attributes
    ----------
    encode : callable
        ``encode(*values) -> bytes``, as described above.
    template : bytes
        The prototype's serialisation with its padding bytes zeroed.
    """

    __slots__ = ('type_name', 'groups', 'template', 'encode', 'fields')

    def __init__(self, prototype: Any, type_name: str, groups: Sequence[Sequence[str]]) -> None:
        data = serialize(prototype, type_name)
        lay = layout(data, type_name)
        self.type_name = type_name
        self.groups = tuple(tuple(g) for g in groups)
        self.template = template = _zero_padding(data, lay)
        self.fields = {path: lay.fields[path] for group in self.groups for path in group
                       if path in lay.fields}
        fmt, pos = '<', 0
        constants: dict[str, bytes] = {}     # name in the generated code -> constant bytes
        arguments = []                       # pack's arguments, in the generated code
        for k, group in enumerate(self.groups):
            group_fmt, start, end = _group_format(lay, group)
            if start < pos:
                raise LayoutError(f'{group[0]} lies before the end of the previous group '
                                  '(groups go in the order of their bytes)')
            if start > pos:
                fmt += f'{start - pos}s'
                constants[f'c{k}'] = template[pos:start]
                arguments.append(f'c{k}')
            fmt += group_fmt
            arguments.append(f'*v{k}')
            pos = end
        if pos < len(template):
            fmt += f'{len(template) - pos}s'
            constants['tail'] = template[pos:]
            arguments.append('tail')
        self.encode = _packer(struct.Struct(fmt).pack, len(self.groups), arguments, constants)
        # packing the prototype's own values must give its serialisation back, byte for byte
        # (float32 fields included: struct rounds as the C conversion does)
        values = [_flat(prototype, group) for group in self.groups]
        try:
            again = self.encode(*values)
        except struct.error as exc:
            raise LayoutError(f'{type_name}: {exc}') from None
        if again != template:
            raise LayoutError(f'{type_name}: the template does not round-trip')

    def rows(self, columns: Mapping[str, Any], n: int) -> NDArray[np.uint8]:
        """``n`` messages at once, as rows of an ``(n, len(template))`` byte array: row ``i``
        is what :attr:`encode` returns for the values of row ``i`` of ``columns``.

        ``columns`` maps each path of :attr:`groups` to an array of shape ``(n,)`` or
        ``(n, count)`` (its count of values per message, as in the prototype). The rows of a
        run differ only in numbers, so each field is one strided copy of its column into the
        template's rows (no per-message work): the columnar form of :attr:`encode`, used to
        record whole offline runs. ``ValueError`` for a path that is not in :attr:`groups` or
        a column of the wrong shape.
        """
        out = np.empty((n, len(self.template)), dtype=np.uint8)
        out[:] = np.frombuffer(self.template, dtype=np.uint8)
        missing = set(self.fields) - set(columns)
        if missing:
            raise ValueError(f'{self.type_name}: no column for {", ".join(sorted(missing))}')
        for path, values in columns.items():
            if path not in self.fields:
                raise ValueError(f'{self.type_name}: {path} is not a field of the encoder')
            offset, count, dtype = self.fields[path]
            arr = np.asarray(values)
            if arr.shape not in ((n, count), (n,) if count == 1 else (n, count)):
                raise ValueError(f'{self.type_name}: column {path} has shape {arr.shape}, '
                                 f'expected ({n}, {count})')
            # numbers packed little-endian as struct packs them (a float column to an integer
            # field would be truncated there too; the callers pass the field's own type)
            col = np.ascontiguousarray(arr.reshape(n, count), dtype=np.dtype(dtype))
            width = col.dtype.itemsize * count
            out[:, offset:offset + width] = col.view(np.uint8).reshape(n, width)
        return out


def _packer(pack: Any, count: int, arguments: list[str], constants: dict[str, bytes]) -> Any:
    """``encode(v0, ..., v{count-1})``: ``pack`` of ``arguments`` (constant names and
    unpacked groups), made as code once so that a message costs one call and one ``pack``, no
    loop over its groups (half the time of a loop for a JointState). The code is made only of
    the generated names ``v<k>``, ``c<k>`` and ``tail``."""
    params = ', '.join(f'v{k}' for k in range(count))
    source = f'def encode({params}):\n    return pack({", ".join(arguments)})\n'
    namespace: dict[str, Any] = {'pack': pack, **constants}
    exec(source, namespace)             # noqa: S102 - generated from names, not from input
    return namespace['encode']


def _group_format(lay: Layout, group: Sequence[str]) -> tuple[str, int, int]:
    """``(struct format without byte order, first byte, end byte)`` of the adjacent numeric
    fields ``group`` of a layout; LayoutError if one is not a numeric field or not adjacent."""
    fmt, start, end = '', None, None
    for path in group:
        if path not in lay.fields:
            raise LayoutError(f'{path} is not a numeric field of the prototype')
        offset, n, dtype = lay.fields[path]
        if start is None:
            start = end = offset
        elif offset != end:
            raise LayoutError(f'{path} does not follow the previous field of its group')
        fmt += f'{n}{_STRUCT[dtype]}'
        end = offset + n * np.dtype(dtype).itemsize
    if start is None:
        raise LayoutError('an empty group')
    return fmt, start, end


def set_fields(data: bytes, type_name: str, values: Mapping[str, Any]) -> bytes:
    """CDR ``data`` of ``type_name`` with the numeric fields ``values`` (``{dotted path: number
    or flat sequence}``, e.g. ``{'header.stamp.sec': 12}``) set; the rest of the bytes as they
    were. The message is walked only up to the last of those fields, so setting the stamp of a
    trajectory of a million points costs as little as of an empty one. :class:`LayoutError`
    if a path is not a numeric field of ``data``; ``struct.error`` for a wrong count of
    values."""
    lay = layout(data, type_name, only=values.keys())
    out = bytearray(data)
    for path, value in values.items():
        fmt, start, _ = _group_format(lay, (path,))
        flat = list(value) if isinstance(value, (Sequence, np.ndarray)) else [value]
        struct.pack_into('<' + fmt, out, start, *flat)
    return bytes(out)


def _flat(msg: Any, group: Sequence[str]) -> list:
    out: list = []
    for path in group:
        value = field_value(msg, path)
        if isinstance(value, (bytes, bytearray)):
            out.extend(value)
        elif hasattr(value, '__len__'):
            out.extend(value.tolist() if isinstance(value, np.ndarray) else value)
        else:
            out.append(value)
    return out


def _zero_padding(data: bytes, lay: Layout) -> bytes:
    """``data`` with every byte that is neither header, fixed nor a numeric field set to 0."""
    keep = np.zeros(len(data), dtype=bool)
    keep[:ENCAPSULATION] = True
    keep[np.array(lay.fixed, dtype=np.int64)] = True
    for offset, n, dtype in lay.fields.values():
        keep[offset:offset + n * np.dtype(dtype).itemsize] = True
    out = np.frombuffer(data, dtype=np.uint8).copy()
    out[~keep] = 0
    return out.tobytes()


def zero_padding(data: bytes, type_name: str) -> bytes:
    """CDR ``data`` of ``type_name`` with its padding bytes set to 0, to compare serialisations
    (Fast CDR leaves padding uninitialised)."""
    return _zero_padding(data, layout(data, type_name))

"""
ROS 2 messages as CDR bytes, encoded from their ``.msg`` definitions.

What rosbag2 stores a message as: the 4-byte encapsulation header of little-endian plain CDR
(``00 01 00 00``), then the fields in order, each aligned to its own size counted from after
the header; a string as its byte length plus one (uint32), its UTF-8 bytes and a zero; a
sequence as its length (uint32) then its items; a fixed array as its items alone. Padding is
zeros and nothing follows the last field, so one message gives the same bytes in every process
(rclpy's ``serialize_message`` does neither).

The encoders are built from the concatenated definition rosbag2 stores in a bag's schema (the
type's ``.msg`` text, then each dependency after a line of ``=`` and ``MSG: pkg/Type``): any
installed or recorded type, no generated code needed. A message is read by attribute (an rclpy
message, a decoded one) or by key (a mapping).
"""
from __future__ import annotations

import dataclasses
import re
import struct
from typing import Any, Callable

import numpy as np

#: little-endian plain CDR
ENCAPSULATION = b'\x00\x01\x00\x00'
#: each primitive's little-endian numpy type (``char`` is uint8 in ROS 2's interface mapping)
PRIMITIVES = {'bool': '?', 'byte': 'u1', 'char': 'u1', 'int8': 'i1', 'uint8': 'u1',
              'int16': '<i2', 'uint16': '<u2', 'int32': '<i4', 'uint32': '<u4',
              'int64': '<i8', 'uint64': '<u8', 'float32': '<f4', 'float64': '<f8'}
_SECTION = re.compile(r'^=+\s*$', re.MULTILINE)
_FIELD = re.compile(r'^(?P<type>[A-Za-z][\w/]*)(?:<=(?P<string_bound>\d+))?'
                    r'(?:\[(?P<bounded><=)?(?P<size>\d*)\])?$')

Encode = Callable[[bytearray, Any], None]


class EncodingError(ValueError):
    """A definition that cannot be read, or a message that does not fit its definition."""


@dataclasses.dataclass(frozen=True)
class Field:
    """One field of a definition: its name, its item type, and how many items it holds."""

    name: str
    item: str                 # a primitive, 'string', or a nested 'pkg/Type'
    array: str                # '' (one item), 'fixed', 'sequence'
    size: int | None = None   # a fixed array's length, a bounded sequence's bound


def definitions(type_name: str, text: str) -> dict[str, list[Field]]:
    """Return each type's fields, from a concatenated definition of ``type_name`` first."""
    found: dict[str, list[Field]] = {}
    current = _short(type_name)
    for index, section in enumerate(_SECTION.split(text)):
        lines = section.strip('\n').splitlines()
        if index:
            if not lines or not lines[0].startswith('MSG: '):
                raise EncodingError(f'{type_name}: a definition section has no "MSG: " line')
            current = _short(lines.pop(0)[5:].strip())
        found[current] = _fields(current, lines)
    return found


def message_encoder(type_name: str, text: str) -> Callable[[Any], bytes]:
    """Return a function that encodes a message of ``type_name`` (defined by ``text``)."""
    fields = definitions(type_name, text)
    built: dict[str, Encode] = {}
    encode = _type_encoder(_short(type_name), fields, built)

    def to_cdr(message: Any) -> bytes:
        out = bytearray(ENCAPSULATION)
        encode(out, message)
        return bytes(out)
    return to_cdr


def _short(name: str) -> str:
    """'pkg/msg/Type' and 'pkg/Type' alike as 'pkg/Type'."""
    parts = name.strip().split('/')
    return f'{parts[0]}/{parts[-1]}' if len(parts) > 1 else name.strip()


def _fields(type_name: str, lines: list[str]) -> list[Field]:
    package = type_name.split('/')[0]
    fields = []
    for line in lines:
        words = line.split('#', 1)[0].split()
        if not words:
            continue                                          # blank or comment
        if len(words) < 2:
            raise EncodingError(f'{type_name}: cannot read the field line {line!r}')
        if '=' in words[1] or (len(words) > 2 and words[2].startswith('=')):
            continue                                          # a constant: no bytes
        match = _FIELD.match(words[0])
        if match is None:
            raise EncodingError(f'{type_name}: cannot read the field type {words[0]!r}')
        item = match['type']
        if item not in PRIMITIVES and item not in ('string', 'wstring'):
            item = _short(item if '/' in item else f'{package}/{item}')
        array = '' if match['size'] is None else (
            'fixed' if match['size'] and not match['bounded'] else 'sequence')
        size = int(match['size']) if match['size'] else None
        fields.append(Field(words[1], item, array, size))
    return fields


def _value(message: Any, name: str) -> Any:
    return message[name] if isinstance(message, dict) else getattr(message, name)


def _align(out: bytearray, size: int) -> None:
    pad = -(len(out) - len(ENCAPSULATION)) % size
    if pad:
        out += bytes(pad)


def _string(out: bytearray, value: Any) -> None:
    data = str(value).encode('utf-8')
    _align(out, 4)
    out += struct.pack('<I', len(data) + 1) + data + b'\x00'


def _length(out: bytearray, count: int) -> None:
    _align(out, 4)
    out += struct.pack('<I', count)


def _type_encoder(type_name: str, fields: dict[str, list[Field]],
                  built: dict[str, Encode]) -> Encode:
    if type_name in built:
        return built[type_name]
    if type_name not in fields:
        raise EncodingError(f'no definition of {type_name} in the schema')
    parts = [(field.name, _field_encoder(type_name, field, fields, built))
             for field in fields[type_name]]

    def encode(out: bytearray, message: Any) -> None:
        if not parts:      # an empty message: the one byte ROS 2's IDL mapping gives it
            out += b'\x00'
        for name, part in parts:
            part(out, _value(message, name))
    built[type_name] = encode
    return encode


def _field_encoder(owner: str, field: Field, fields: dict[str, list[Field]],
                   built: dict[str, Encode]) -> Encode:
    if field.item == 'wstring':
        raise EncodingError(f'{owner}.{field.name}: wstring is not encoded')
    if field.item in PRIMITIVES:
        return _primitive_encoder(owner, field)
    item = (_string if field.item == 'string'
            else _type_encoder(field.item, fields, built))
    if not field.array:
        return item
    check = _count_check(owner, field)

    def items(out: bytearray, values: Any) -> None:
        values = list(values)
        check(len(values))
        if field.array == 'sequence':
            _length(out, len(values))
        for value in values:
            item(out, value)
    return items


def _primitive_encoder(owner: str, field: Field) -> Encode:
    dtype = np.dtype(PRIMITIVES[field.item])
    size = dtype.itemsize
    if not field.array:
        def one(out: bytearray, value: Any) -> None:
            if isinstance(value, (bytes, bytearray)):      # rclpy's byte: a bytes of one
                value = value[0]
            elif isinstance(value, str):                   # a char given as a character
                value = ord(value)
            _align(out, size)
            out += np.asarray(value, dtype=dtype).tobytes()
        return one
    check = _count_check(owner, field)

    def many(out: bytearray, values: Any) -> None:
        if isinstance(values, (list, tuple)) and values and isinstance(values[0], bytes):
            values = b''.join(values)                      # rclpy's byte[]: bytes of one
        if isinstance(values, (bytes, bytearray, memoryview)):
            data = np.frombuffer(values, dtype=np.uint8).astype(dtype, copy=False)
        else:
            data = np.asarray(values, dtype=dtype).reshape(-1)
        check(data.size)
        if field.array == 'sequence':
            _length(out, data.size)
        if data.size:
            _align(out, size)
            out += data.tobytes()
    return many


def _count_check(owner: str, field: Field) -> Callable[[int], None]:
    def check(count: int) -> None:
        if field.array == 'fixed' and count != field.size:
            raise EncodingError(f'{owner}.{field.name}: {count} items where the definition '
                                f'fixes {field.size}')
        if field.array == 'sequence' and field.size is not None and count > field.size:
            raise EncodingError(f'{owner}.{field.name}: {count} items, more than its bound '
                                f'{field.size}')
    return check

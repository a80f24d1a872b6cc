"""ROS 1 message definitions: parse ``.msg`` text, compute md5 sums as genmsg does, decode."""

from __future__ import annotations

import hashlib
import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "HEADER_DEFINITION",
    "SEPARATOR",
    "MessageDefinitionError",
    "MsgField",
    "MsgSpec",
    "compile_decoder",
    "md5sum",
    "parse_full_definition",
    "parse_msg",
]

#: The text of ``std_msgs/Header``, fields only (comments do not change the md5 sum).
HEADER_DEFINITION = "uint32 seq\ntime stamp\nstring frame_id\n"
#: Separator between the main message and each dependency in a full definition.
SEPARATOR = "\n" + "=" * 80 + "\n"

_PRIMITIVES: dict[str, str] = {
    "bool": "B",
    "int8": "b",
    "uint8": "B",
    "byte": "b",
    "char": "B",
    "int16": "h",
    "uint16": "H",
    "int32": "i",
    "uint32": "I",
    "int64": "q",
    "uint64": "Q",
    "float32": "f",
    "float64": "d",
    "time": "II",
    "duration": "ii",
}
_BUILTINS = frozenset(_PRIMITIVES) | {"string"}
_U32 = struct.Struct("<I")


class MessageDefinitionError(ValueError):
    """A message definition cannot be parsed or a referenced type is missing."""


@dataclass(frozen=True)
class MsgField:
    """One field: base type (package-qualified for messages), name, array length."""

    base_type: str
    name: str
    is_array: bool = False
    array_len: int | None = None  # None with is_array: variable length

    @property
    def type_text(self) -> str:
        """The type as written in the md5 text (``uint8[]``, ``float32[3]``)."""
        if not self.is_array:
            return self.base_type
        return f"{self.base_type}[{'' if self.array_len is None else self.array_len}]"

    @property
    def builtin(self) -> bool:
        """True for primitive types and strings (not nested messages)."""
        return self.base_type in _BUILTINS


@dataclass(frozen=True)
class MsgSpec:
    """A parsed message: its full type name, constants (md5 text lines) and fields."""

    full_name: str
    fields: tuple[MsgField, ...]
    constants: tuple[str, ...] = ()
    text: str = field(default="", compare=False)

    @property
    def names(self) -> tuple[str, ...]:
        """Field names in order."""
        return tuple(f.name for f in self.fields)


def _strip_comment(line: str) -> str:
    return line.split("#", 1)[0].strip()


def _qualify(type_name: str, package: str) -> str:
    if type_name in _BUILTINS or "/" in type_name:
        return type_name
    if type_name == "Header":
        return "std_msgs/Header"
    return f"{package}/{type_name}"


def parse_msg(full_name: str, text: str) -> MsgSpec:
    """Parse one ``.msg`` text the way genmsg does (comments, constants, arrays)."""
    package = full_name.split("/", 1)[0] if "/" in full_name else ""
    fields: list[MsgField] = []
    constants: list[str] = []
    for line in text.split("\n"):
        clean = _strip_comment(line)
        if not clean:
            continue
        if "=" in clean:
            constants.append(_constant_text(line, clean))
            continue
        parts = clean.split()
        if len(parts) != 2:
            raise MessageDefinitionError(f"bad field line in {full_name}: {line!r}")
        type_text, name = parts
        is_array = type_text.endswith("]")
        array_len: int | None = None
        base = type_text
        if is_array:
            base, _, size = type_text[:-1].partition("[")
            try:
                array_len = int(size) if size else None
            except ValueError as exc:
                raise MessageDefinitionError(f"bad array size in {line!r}") from exc
        fields.append(MsgField(_qualify(base, package), name, is_array, array_len))
    return MsgSpec(full_name, tuple(fields), tuple(constants), text)


def _constant_text(line: str, clean: str) -> str:
    type_name = clean.split()[0]
    if type_name == "string":  # a string constant's value runs to the end of the line
        name = line[line.find(" ") + 1 : line.find("=")]
        value = line[line.find("=") + 1 :].strip()
        return f"string {name.strip()}={value}"
    name, _, value = " ".join(clean.split()[1:]).partition("=")
    return f"{type_name} {name.strip()}={value.strip()}"


def parse_full_definition(full_name: str, text: str) -> dict[str, MsgSpec]:
    """Parse a connection header's ``message_definition`` (main message + ``MSG:`` deps)."""
    text = text.replace("roslib/Header", "std_msgs/Header")
    chunks = text.split(SEPARATOR)
    specs = {full_name: parse_msg(full_name, chunks[0])}
    for chunk in chunks[1:]:
        first, _, body = chunk.partition("\n")
        if not first.startswith("MSG:"):
            raise MessageDefinitionError(f"dependency without a MSG: line: {first!r}")
        dep_name = first[4:].strip()
        specs[dep_name] = parse_msg(dep_name, body)
    specs.setdefault("std_msgs/Header", parse_msg("std_msgs/Header", HEADER_DEFINITION))
    return specs


def md5sum(full_name: str, specs: dict[str, MsgSpec]) -> str:
    """The md5 sum of a message type as genmsg computes it (nested types by their md5)."""
    spec = _lookup(full_name, specs)
    lines = list(spec.constants)
    for fld in spec.fields:
        if fld.builtin:
            lines.append(f"{fld.type_text} {fld.name}")
        else:
            lines.append(f"{md5sum(fld.base_type, specs)} {fld.name}")
    return hashlib.md5("\n".join(lines).strip().encode()).hexdigest()


def _lookup(name: str, specs: dict[str, MsgSpec]) -> MsgSpec:
    try:
        return specs[name]
    except KeyError:
        raise MessageDefinitionError(f"message type {name} is not defined") from None


Decoder = Callable[[bytes, int], tuple[Any, int]]


def compile_decoder(full_name: str, specs: dict[str, MsgSpec]) -> Callable[[bytes], dict[str, Any]]:
    """A function decoding one serialised message into a dict (nested messages as dicts)."""
    decode = _message_decoder(full_name, specs, depth=0)

    def decode_message(data: bytes) -> dict[str, Any]:
        try:
            value, _ = decode(data, 0)
        except (struct.error, IndexError, UnicodeDecodeError) as exc:
            raise MessageDefinitionError(f"truncated or malformed {full_name}: {exc}") from exc
        result: dict[str, Any] = value
        return result

    return decode_message


def _message_decoder(name: str, specs: dict[str, MsgSpec], depth: int) -> Decoder:
    if depth > 16:
        raise MessageDefinitionError(f"message nesting too deep at {name}")
    # Each step yields the values of one or more fields, in order.
    steps: list[tuple[tuple[str, ...], Decoder]] = []
    run_names: list[str] = []
    run_formats: list[str] = []

    def flush() -> None:
        if run_names:
            steps.append((tuple(run_names), _fixed_decoder(run_formats)))
            run_names.clear()
            run_formats.clear()

    for fld in _lookup(name, specs).fields:
        if fld.base_type in _PRIMITIVES and not fld.is_array:
            run_names.append(fld.name)
            run_formats.append(_PRIMITIVES[fld.base_type])
            continue
        flush()
        steps.append(((fld.name,), _single(_field_decoder(fld, specs, depth))))
    flush()

    def decode(data: bytes, offset: int) -> tuple[dict[str, Any], int]:
        out: dict[str, Any] = {}
        for names, step in steps:
            values, offset = step(data, offset)
            out.update(zip(names, values, strict=True))
        return out, offset

    return decode


def _single(decoder: Decoder) -> Decoder:
    def decode(data: bytes, offset: int) -> tuple[Any, int]:
        value, offset = decoder(data, offset)
        return (value,), offset

    return decode


def _fixed_decoder(formats: list[str]) -> Decoder:
    """Values of a run of fixed-size fields; a time or duration is one (secs, nsecs) tuple."""
    packer = struct.Struct("<" + "".join(formats))
    widths = [len(fmt) for fmt in formats]
    simple = all(width == 1 for width in widths)

    def decode(data: bytes, offset: int) -> tuple[Any, int]:
        raw = packer.unpack_from(data, offset)
        if simple:
            return raw, offset + packer.size
        values: list[Any] = []
        i = 0
        for width in widths:
            values.append(raw[i] if width == 1 else tuple(raw[i : i + width]))
            i += width
        return values, offset + packer.size

    return decode


def _string(data: bytes, offset: int) -> tuple[str, int]:
    (size,) = _U32.unpack_from(data, offset)
    end = offset + 4 + size
    if end > len(data):
        raise IndexError("string runs past the end of the message")
    return data[offset + 4 : end].decode("utf-8", "replace"), end


def _field_decoder(fld: MsgField, specs: dict[str, MsgSpec], depth: int) -> Decoder:
    base = fld.base_type
    element: Decoder
    if base == "string":
        element = _string
    elif base in _PRIMITIVES:
        run = _fixed_decoder([_PRIMITIVES[base]])

        def element(data: bytes, offset: int) -> tuple[Any, int]:
            values, offset = run(data, offset)
            return values[0], offset

    else:
        element = _message_decoder(base, specs, depth + 1)
    if not fld.is_array:
        return element
    fixed_len = fld.array_len

    def decode_array(data: bytes, offset: int) -> tuple[Any, int]:
        count = fixed_len
        if count is None:
            (count,) = _U32.unpack_from(data, offset)
            offset += 4
        if base in ("uint8", "char"):
            end = offset + count
            if end > len(data):
                raise IndexError("byte array runs past the end of the message")
            return bytes(data[offset:end]), end
        if count > len(data):  # each element takes at least a byte
            raise IndexError("array longer than the message")
        items: list[Any] = []
        for _ in range(count):
            item, offset = element(data, offset)
            items.append(item)
        return items, offset

    return decode_array

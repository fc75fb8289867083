"""Safe readers for user files: bounded size, clear decoding, JSON with limits, finite numbers.

Every reader of user input (styles, robot configs, command keyframes, autosave recovery files and
the motion / BVH / frame-file readers that follow) goes through these helpers, so that bad input
always ends as ONE line naming the file, the field path and what was expected — never a
traceback, a hang or a partly written output::

    from engine.safe_io import ReadError, read_json

    try:
        doc = read_json(path)               # bytes → UTF-8 text → JSON, all checked
    except ReadError as exc:
        print(exc)                          # "neutral.json: samples.in_place: duplicate key ..."

API (all raise :class:`ReadError` with ``source``, ``field_path`` and ``detail``):

- ``read_bytes(path, max_bytes=MAX_FILE_BYTES)`` — the file's bytes, refusing a missing file, a
  folder, an unreadable file or one larger than ``max_bytes`` (read stops at the limit: a huge
  file is never loaded).
- ``decode_text(data, source)`` — UTF-8 (a UTF-8 BOM is dropped); refuses UTF-16/32, invalid
  bytes (names the byte offset) and NUL bytes (binary files).
- ``read_text(path, max_bytes=...)`` — both of the above.
- ``parse_json(text, source, max_depth=MAX_JSON_DEPTH)`` — JSON with: a nesting-depth limit
  (checked before parsing, so no RecursionError), duplicate keys refused with their path,
  NaN/Infinity kept as float (callers check finiteness where they need numbers), integers longer
  than ``MAX_INT_DIGITS`` read as floats (so no ``int`` conversion limit error), syntax errors as
  ``line L column C: expected valid JSON (...)`` with a complete sentence.
- ``read_json(path, max_bytes=..., max_depth=...)`` — read_text + parse_json.
- ``finite_number(value, field_path, source)`` — a real finite number (bool refused).
- ``nesting_depth(text)`` — the deepest ``[``/``{`` nesting of JSON text, strings ignored.
"""

from __future__ import annotations

import codecs
import json
import math
import os
import re
import stat
from pathlib import Path
from typing import Any

import numpy as np

MAX_FILE_BYTES = 16 * 1024 * 1024  # a style is ~50 kB; motions use their own, larger limit
MAX_JSON_DEPTH = 64  # a style nests 6 deep
MAX_INT_DIGITS = 300


class ReadError(ValueError):
    """A user file that cannot be read: ``source: field.path: what was expected``."""

    def __init__(self, source: str, field_path: str, detail: str):
        self.source = source
        self.field_path = field_path
        self.detail = detail
        super().__init__(one_line(source, field_path, detail))


def one_line(source: str, field_path: str, detail: str) -> str:
    """``source: field_path: detail`` (no empty parts), always a single line."""
    parts = [_clip(p, n) for p, n in ((source, 200), (field_path, 160), (detail, 240)) if p]
    return ": ".join(parts).replace("\r", " ").replace("\n", " ")


def _clip(text: str, n: int) -> str:
    return text if len(text) <= n else text[: n - 1] + "…"


def _size(n: int) -> str:
    return f"{n / 1048576:.1f} MiB" if n >= 1048576 else f"{n} bytes"


def read_bytes(path: str | os.PathLike, max_bytes: int = MAX_FILE_BYTES, source: str | None = None) -> bytes:
    path = Path(path)
    source = source if source is not None else str(path)
    try:
        mode = os.stat(path).st_mode
        if stat.S_ISDIR(mode):
            raise IsADirectoryError
        if not stat.S_ISREG(mode):  # a FIFO or a device would block or never end
            raise ReadError(source, "", "expected a regular file (this is a device, FIFO or socket)")
        with open(path, "rb") as f:
            data = f.read(max_bytes + 1)
    except FileNotFoundError:
        raise ReadError(source, "", "file not found") from None
    except IsADirectoryError:
        raise ReadError(source, "", "expected a file, this is a folder") from None
    except PermissionError:
        raise ReadError(source, "", "expected a readable file (permission denied)") from None
    except OSError as exc:
        raise ReadError(source, "", f"expected a readable file ({exc.strerror or exc})") from None
    if len(data) > max_bytes:
        raise ReadError(source, "", f"expected at most {_size(max_bytes)}, the file is larger")
    return data


_BOMS = ((codecs.BOM_UTF32_LE, "UTF-32"), (codecs.BOM_UTF32_BE, "UTF-32"), (codecs.BOM_UTF16_LE, "UTF-16"),
         (codecs.BOM_UTF16_BE, "UTF-16"))


def decode_text(data: bytes, source: str) -> str:
    if data.startswith(codecs.BOM_UTF8):
        data = data[len(codecs.BOM_UTF8):]
    else:
        for bom, name in _BOMS:
            if data.startswith(bom):
                raise ReadError(source, "", f"expected UTF-8 text, the file is {name}; save it as UTF-8")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        bad = data[exc.start:exc.start + 1].hex()
        raise ReadError(source, f"byte {exc.start}", f"expected UTF-8 text, got byte 0x{bad}") from None
    nul = text.find("\0")
    if nul >= 0:
        raise ReadError(source, f"byte {len(text[:nul].encode())}", "expected text, got a NUL byte (a binary file?)")
    return text


def read_text(path: str | os.PathLike, max_bytes: int = MAX_FILE_BYTES, source: str | None = None) -> str:
    source = source if source is not None else str(path)
    return decode_text(read_bytes(path, max_bytes, source), source)


_STRING = re.compile(r'"(?:[^"\\]|\\.)*"', re.S)


def nesting_depth(text: str) -> tuple[int, int]:
    """(deepest [ / { nesting, character offset where it is reached) of JSON text; strings ignored."""
    stripped = _STRING.sub('""', text)
    codes = np.frombuffer(stripped.encode("utf-32-le"), dtype=np.uint32)
    step = np.zeros(len(codes), dtype=np.int32)
    step[(codes == ord("[")) | (codes == ord("{"))] = 1
    step[(codes == ord("]")) | (codes == ord("}"))] = -1
    if not len(step):
        return 0, 0
    depth = np.cumsum(step)
    i = int(np.argmax(depth))
    return int(depth[i]), i


class _Duplicate:
    def __init__(self) -> None:
        self.found: list[tuple[dict, str]] = []

    def hook(self, pairs: list[tuple[str, Any]]) -> dict:
        d: dict = {}
        for k, v in pairs:
            if k in d and not self.found:
                self.found.append((d, k))
            d[k] = v
        return d


def _path_of(root: Any, target: dict) -> str | None:
    stack: list[tuple[Any, str]] = [(root, "")]
    while stack:
        node, path = stack.pop()
        if node is target:
            return path
        if isinstance(node, dict):
            stack.extend((v, f"{path}.{k}" if path else str(k)) for k, v in node.items())
        elif isinstance(node, list):
            stack.extend((v, f"{path}[{i}]") for i, v in enumerate(node))
    return None


def _parse_int(s: str) -> int | float:
    return int(s) if len(s) <= MAX_INT_DIGITS else float(s)


def _position(text: str, offset: int) -> str:
    line = text.count("\n", 0, offset) + 1
    col = offset - (text.rfind("\n", 0, offset) + 1) + 1
    return f"line {line} column {col}"


def parse_json(text: str, source: str, max_depth: int = MAX_JSON_DEPTH) -> Any:
    if not text.strip():
        raise ReadError(source, "", "expected JSON, the file is empty")
    depth, at = nesting_depth(text)
    if depth > max_depth:
        raise ReadError(source, _position(text, at), f"expected at most {max_depth} nested lists/objects, got {depth}")
    dup = _Duplicate()
    try:
        data = json.loads(text, object_pairs_hook=dup.hook, parse_int=_parse_int,
                          parse_constant=float)
    except json.JSONDecodeError as exc:
        detail = exc.msg[0].lower() + exc.msg[1:]
        if detail.endswith(" at"):  # "Unterminated string starting at" → complete the sentence
            detail = detail[:-3] + " here"
        if exc.pos >= len(text.rstrip()) or detail.startswith("unterminated string"):
            detail += "; the file ends early (truncated?)"
        raise ReadError(source, f"line {exc.lineno} column {exc.colno}", f"expected valid JSON ({detail})") from None
    except RecursionError:  # a fallback: the depth check above should always catch it first
        raise ReadError(source, "", f"expected at most {max_depth} nested lists/objects") from None
    except ValueError as exc:
        raise ReadError(source, "", f"expected valid JSON ({exc})") from None
    if dup.found:
        obj, key = dup.found[0]
        where = _path_of(data, obj)
        field_path = f"{where}.{key}" if where else key
        raise ReadError(source, field_path, f"duplicate key {key!r}; expected each key once")
    return data


def read_json(path: str | os.PathLike, max_bytes: int = MAX_FILE_BYTES, max_depth: int = MAX_JSON_DEPTH,
              source: str | None = None) -> Any:
    source = source if source is not None else str(path)
    return parse_json(read_text(path, max_bytes, source), source, max_depth)


def finite_number(value: Any, field_path: str, source: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        shown = type(value).__name__ if isinstance(value, (dict, list)) else repr(value)[:40]
        raise ReadError(source, field_path, f"expected a number, got {shown}")
    try:
        x = float(value)
    except OverflowError:
        x = math.inf
    if not math.isfinite(x):
        raise ReadError(source, field_path, f"expected a finite number, got {x}")
    return x

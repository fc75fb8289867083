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
- ``read_npz(path, max_bytes=MAX_NPZ_BYTES, max_data_bytes=MAX_NPZ_DATA_BYTES, kinds="biufUS", only=None)`` — the arrays
  of an npz archive without pickle and without trusting its headers: every entry must be a stored or
  deflated ``.npy`` (no bz2/lzma: their decompressors are unbounded), named once (a zip may hold one name
  twice: refused with the array's name), its declared size and its header's shape × itemsize checked
  against ``max_data_bytes`` *before* anything is decompressed or allocated (a zip bomb or a header
  declaring 10¹² elements is refused in microseconds), its dtype one of ``kinds`` (object and structured
  dtypes never), its data exactly as long as the header says. The field path of an error is the array's
  name: ``x.npz: qpos: expected at most 256.0 MiB of array data, the header declares (1000000000, 19) float64``.
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
MAX_NPZ_BYTES = 256 * 1024 * 1024  # a motion npz is a few MB (a 10-minute humanoid motion ≈ 9 MB)
MAX_NPZ_DATA_BYTES = 256 * 1024 * 1024  # all arrays together, decompressed
MAX_NPZ_ARRAYS = 10_000
_NPY_HEADER_BYTES = 16 * 1024  # numpy reads headers of at most 10 000 characters


class ReadError(ValueError):
    """A user file that cannot be read: ``source: field.path: what was expected``."""

    def __init__(self, source: str, field_path: str, detail: str):
        self.source = source
        self.field_path = field_path
        self.detail = detail
        super().__init__(one_line(source, field_path, detail))

    def __reduce__(self):  # pickled across processes (Ray): rebuilt from its three parts
        return type(self), (self.source, self.field_path, self.detail)


def split_message(message: str) -> tuple[str, str, str]:
    """(source, field_path, detail) of a ``source: field: detail`` message built as one string (readers that
    raise ``SomeError(f"{name}: {field}: expected …")``); the field is taken only when it is one token."""
    source, sep, rest = message.partition(": ")
    if not sep:
        return "", "", message
    field, sep, detail = rest.partition(": ")
    if sep and field and " " not in field and len(field) <= 80:
        return source, field, detail
    return source, "", rest


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
        st = os.stat(path)
        if stat.S_ISDIR(st.st_mode):
            raise IsADirectoryError
        if not stat.S_ISREG(st.st_mode):  # a FIFO or a device would block or never end
            raise ReadError(source, "", "expected a regular file (this is a device, FIFO or socket)")
        if st.st_size > max_bytes:  # refused before reading (the read below also stops there)
            raise ReadError(source, "", f"expected at most {_size(max_bytes)}, the file is larger")
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


def _checked_file(path: Path, source: str, max_bytes: int) -> None:
    """A regular, existing file of at most ``max_bytes`` (the checks of :func:`read_bytes`, nothing read)."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise ReadError(source, "", "file not found") from None
    except PermissionError:
        raise ReadError(source, "", "expected a readable file (permission denied)") from None
    except OSError as exc:
        raise ReadError(source, "", f"expected a readable file ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise ReadError(source, "", "expected a file, this is a folder")
    if not stat.S_ISREG(st.st_mode):
        raise ReadError(source, "", "expected a regular file (this is a device, FIFO or socket)")
    if st.st_size > max_bytes:
        raise ReadError(source, "", f"expected at most {_size(max_bytes)}, the file is larger")


_DTYPE_KINDS = {"b": "booleans", "i": "integers", "u": "integers", "f": "floats", "c": "complex numbers",
                "U": "text", "S": "bytes"}


def _npy_entry(zf: Any, info: Any, key: str, source: str, budget: int, kinds: str) -> np.ndarray:
    """One ``.npy`` member of an open zip, its header checked before its data is read."""
    from numpy.lib import format as npy_format

    with zf.open(info) as member:
        try:
            version = npy_format.read_magic(member)
            if version == (1, 0):
                shape, fortran, dtype = npy_format.read_array_header_1_0(member)
            elif version == (2, 0):
                shape, fortran, dtype = npy_format.read_array_header_2_0(member)
            else:
                raise ValueError(f"npy format version {version}")
        except Exception as exc:  # noqa: BLE001 - numpy's header parser raises many kinds; all mean "not an array"
            detail = str(exc).splitlines()[0][:120] if str(exc) else type(exc).__name__
            raise ReadError(source, key, f"expected a .npy array ({detail})") from None
        header_bytes = member.tell() if member.seekable() else None
        allowed = ", ".join(sorted({_DTYPE_KINDS[k] for k in kinds if k in _DTYPE_KINDS}))
        if dtype.hasobject:
            raise ReadError(source, key, f"expected {allowed}, got Python objects (never unpickled)")
        if dtype.kind not in kinds or dtype.fields is not None or dtype.subdtype is not None:
            raise ReadError(source, key, f"expected {allowed}, got dtype {dtype}")
        if dtype.itemsize == 0:
            raise ReadError(source, key, f"expected a dtype with a size, got {dtype}")
        if any(d < 0 for d in shape) or len(shape) > 32:
            raise ReadError(source, key, f"expected a valid array shape, got {shape}")
        count = math.prod(shape)
        nbytes = count * dtype.itemsize
        if nbytes > budget:
            raise ReadError(source, key, f"expected at most {_size(budget)} of array data, the header declares "
                            f"{shape} {dtype} ({_size(nbytes)})")
        if header_bytes is not None and header_bytes + nbytes != info.file_size:
            raise ReadError(source, key, f"expected {nbytes} bytes of data for shape {shape} {dtype}, the entry "
                            f"holds {info.file_size - header_bytes}")
        buf = bytearray(nbytes)
        view = memoryview(buf)
        got = 0
        while got < nbytes:
            n = member.readinto(view[got:])
            if not n:
                break
            got += n
        if got < nbytes:
            raise ReadError(source, key, f"expected {nbytes} bytes of data for shape {shape} {dtype}, the file ends "
                            f"after {got} (truncated?)")
        member.read(1)  # the end of the entry: zipfile checks its CRC there
    flat = np.frombuffer(buf, dtype=dtype, count=count)
    if fortran:
        return flat.reshape(shape[::-1]).transpose()
    return flat.reshape(shape)


def read_npz(path: str | os.PathLike, max_bytes: int = MAX_NPZ_BYTES, max_data_bytes: int = MAX_NPZ_DATA_BYTES,
             source: str | None = None, kinds: str = "biufUS", only: tuple[str, ...] | None = None
             ) -> dict[str, np.ndarray]:
    """The arrays of an npz archive, every header checked before anything is allocated (see module docstring);
    ``only``: read just these arrays (the archive's directory is still checked whole)."""
    import zipfile
    import zlib

    path = Path(path)
    source = source if source is not None else str(path)
    _checked_file(path, source, max_bytes)
    try:
        zf = zipfile.ZipFile(path)
    except FileNotFoundError:
        raise ReadError(source, "", "file not found") from None
    except PermissionError:
        raise ReadError(source, "", "expected a readable file (permission denied)") from None
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, NotImplementedError) as exc:
        detail = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
        raise ReadError(source, "", f"expected an npz archive (a zip of .npy arrays): {detail}") from None
    with zf:
        entries: dict[str, Any] = {}
        declared = 0
        for info in zf.infolist():
            name = info.filename
            if info.is_dir():
                continue
            key = name[:-4] if name.endswith(".npy") else name
            if not name.endswith(".npy"):
                raise ReadError(source, key[:80], "expected only .npy arrays in the npz archive")
            if key in entries:
                raise ReadError(source, key[:80], "the archive holds this array twice; expected each array once")
            if info.compress_type not in (zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED):
                raise ReadError(source, key[:80], f"expected a stored or deflated entry (numpy's), got compression "
                                f"method {info.compress_type}")
            if info.flag_bits & 0x1:
                raise ReadError(source, key[:80], "expected an unencrypted entry")
            if len(entries) >= MAX_NPZ_ARRAYS:
                raise ReadError(source, "", f"expected at most {MAX_NPZ_ARRAYS} arrays in the npz archive")
            declared += max(0, info.file_size - _NPY_HEADER_BYTES)  # the data, beside the header
            if declared > max_data_bytes:
                raise ReadError(source, key[:80], f"expected at most {_size(max_data_bytes)} of array data, the "
                                f"archive declares {_size(declared)} (a zip bomb?)")
            entries[key] = info
        if not entries:
            raise ReadError(source, "", "expected an npz archive with arrays, it holds none")
        out: dict[str, np.ndarray] = {}
        budget = max_data_bytes
        for key, info in entries.items():
            if only is not None and key not in only:
                continue
            try:
                arr = _npy_entry(zf, info, key[:80], source, budget, kinds)
            except ReadError:
                raise
            except Exception as exc:  # noqa: BLE001 - zipfile/zlib errors: a corrupt or truncated entry
                detail = str(exc).splitlines()[0][:100] if str(exc) else type(exc).__name__
                raise ReadError(source, key[:80], f"expected a readable .npy entry ({detail})") from None
            budget -= arr.nbytes
            out[key] = arr
        return out

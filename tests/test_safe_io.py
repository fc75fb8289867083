"""engine.safe_io: every malformed file ends as one complete line naming the file, field and expectation."""

from __future__ import annotations

import json
import math

import pytest

from engine import safe_io
from engine.safe_io import ReadError, read_json, read_text


def _err(path, **kw) -> ReadError:
    with pytest.raises(ReadError) as info:
        read_json(path, **kw)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(str(path)) and ": :" not in msg and not msg.endswith(" at")
    return info.value


def test_deep_nesting_is_refused_before_parsing(tmp_path):
    p = tmp_path / "deep.json"
    p.write_text("[" * 200_000 + "]" * 200_000)
    e = _err(p)
    assert e.field_path == "line 1 column 200000" and "at most 64 nested" in e.detail


def test_brackets_inside_strings_do_not_count_as_nesting(tmp_path):
    p = tmp_path / "s.json"
    p.write_text(json.dumps({"a": "[" * 1000, "b": ["{\\\"", "]]"]}))
    assert read_json(p)["a"] == "[" * 1000


def test_truncated_json_gives_a_complete_sentence(tmp_path):
    p = tmp_path / "t.json"
    p.write_text('{"schema": "motion-studio/sty')
    e = _err(p)
    assert e.detail == "expected valid JSON (unterminated string starting here; the file ends early (truncated?))"
    p.write_text('{"a": [1, 2,')
    assert "ends early" in _err(p).detail


def test_missing_file_has_no_empty_field(tmp_path):
    assert str(_err(tmp_path / "nope.json")) == f"{tmp_path / 'nope.json'}: file not found"
    assert "folder" in _err(tmp_path).detail


def test_duplicate_keys_name_their_path(tmp_path):
    p = tmp_path / "d.json"
    p.write_text('{"samples": {"in_place": {"intervals": 1, "intervals": 2}}}')
    e = _err(p)
    assert e.field_path == "samples.in_place.intervals" and "duplicate key" in e.detail
    p.write_text('[{"a": 1}, {"b": [{"c": 1, "c": 1}]}]')
    assert _err(p).field_path == "[1].b[0].c"


def test_encodings_binary_and_empty(tmp_path):
    p = tmp_path / "e.json"
    p.write_bytes('{"a": 1}'.encode("utf-16"))
    assert "UTF-16" in _err(p).detail
    p.write_bytes(b'{"a": "caf\xe9"}')
    e = _err(p)
    assert e.field_path == "byte 10" and "0xe9" in e.detail
    p.write_bytes(b'{"a": 1}\x00\x00')
    assert "NUL" in _err(p).detail
    p.write_bytes(b"\xef\xbb\xbf" + b'{"a": 1}')  # a UTF-8 BOM is fine
    assert read_json(p) == {"a": 1}
    p.write_bytes(b"  \n")
    assert "empty" in _err(p).detail


def test_size_limit_stops_reading(tmp_path):
    p = tmp_path / "big.json"
    p.write_bytes(b" " * 2048 + b"{}")
    assert "at most 1024 bytes" in _err(p, max_bytes=1024).detail
    assert read_json(p, max_bytes=4096) == {}


def test_numbers_huge_nan_inf(tmp_path):
    p = tmp_path / "n.json"
    p.write_text('{"a": ' + "9" * 5000 + ', "b": NaN, "c": -Infinity, "d": 1e999}')
    d = read_json(p)
    assert d["a"] == math.inf and math.isnan(d["b"]) and d["c"] == -math.inf and d["d"] == math.inf
    for bad in (d["a"], d["b"], True, "1", [1]):
        with pytest.raises(ReadError, match="x.y: expected a"):
            safe_io.finite_number(bad, "x.y", "f.json")
    assert safe_io.finite_number(10 ** 300, "x", "f") == 1e300


def test_read_text_permission(tmp_path):
    import os

    p = tmp_path / "p.json"
    p.write_text("{}")
    p.chmod(0)
    if os.access(p, os.R_OK):
        pytest.skip("running as root: permissions are not enforced")
    with pytest.raises(ReadError, match="permission denied"):
        read_text(p)


def test_fifo_and_devices_are_refused_without_blocking(tmp_path):
    import os

    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    assert "regular file" in _err(fifo).detail  # opening it would block forever
    with pytest.raises(ReadError, match="regular file"):
        read_text("/dev/zero")

"""Scene files → :class:`~.model.Scene`: TOML (``load_scene``) and the JSON kept beside a
run's outputs (``load_scene_json``), each read with a size limit and a bounded nesting depth,
every key known and every value of its field's type."""
from __future__ import annotations

import dataclasses
import re
import stat
import tomllib
import types
import typing
from pathlib import Path
from typing import Literal, Union

from .model import (LIMITS, MAX_DEPTH, Scene, SceneError)


# --------------------------------------------------------------------------- TOML → dataclasses


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file. Raises SceneError with the file and key named."""
    path = Path(path)
    text = read_text(path, "scene file")
    try:
        _toml_prescan(text)
    except SceneError as e:
        raise SceneError(f"{path}: {e}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(f"{path}: TOML syntax error: {e}") from None
    except RecursionError:
        raise SceneError(f"{path}: {_TOO_DEEP}") from None
    try:
        _check_depth(data)
        _check_unused(data)
        scene = from_dict(Scene, data, "")
        scene.base_dir = str(path.resolve().parent)
        return scene.validate()
    except SceneError as e:
        raise SceneError(f"{path}: {e}") from None


def _check_unused(data: dict) -> None:
    """Keys a file gives that the run would not use (the dataclasses cannot tell a given
    value from a default)."""
    steps = data.get("steps")
    if isinstance(steps, dict) and "times" in steps and "end" in steps:
        raise SceneError("steps.end: unused with 'times' (the run ends at the last time); "
                         "leave it out")


def read_text(path: Path, what: str) -> str:
    """A regular file of at most LIMITS["scene_bytes"], as UTF-8 text. Checked before
    opening: a FIFO would block the read, a device (/dev/zero) never end it."""
    try:
        st = path.stat()
    except OSError as e:
        raise SceneError(f"{path}: cannot read {what} ({e.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise SceneError(f"{path}: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise SceneError(f"{path}: is not a regular file (a device, FIFO or socket), not a "
                         f"{what}")
    if st.st_size > LIMITS["scene_bytes"]:
        raise SceneError(f"{path}: {st.st_size:,} bytes; a {what} has at most "
                         f"{LIMITS['scene_bytes']:,}")
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise SceneError(f"{path}: cannot read {what} ({e.strerror})") from None
    try:
        return raw.decode("utf-8-sig")  # an editor's byte-order mark is not part of the text
    except UnicodeDecodeError as e:
        raise SceneError(f"{path}: not UTF-8 text (byte 0x{raw[e.start]:02x} at offset "
                         f"{e.start})") from None


def load_scene_json(path: str | Path) -> Scene:
    """A scene saved by a run (``DIR/scene.json``), for restarts."""
    path = Path(path)
    try:
        data = json_loads(read_text(path, "saved scene"))
    except ValueError as e:
        raise SceneError(f"{path}: cannot read the saved scene ({e})") from None
    if not isinstance(data, dict):
        raise SceneError(f"{path}: the saved scene is not a JSON object")
    base_dir = data.pop("base_dir", ".")
    try:
        scene = from_dict(Scene, data, "")
        scene.base_dir = base_dir if isinstance(base_dir, str) else "."
        return scene.validate()
    except SceneError as e:
        raise SceneError(f"{path}: {e}") from None


_TOO_DEEP = f"tables and lists nested more than {MAX_DEPTH} levels deep"
#: the characters that neither end a dotted key nor matter to the scan
_SIGNIFICANT = re.compile(r"[^A-Za-z0-9_\- \t]")


def _toml_prescan(text: str) -> None:
    """Bound the nesting of a TOML text before tomllib reads it: tomllib recurses per
    bracket (50 000 of them: RecursionError) and is quadratic in a dotted key's parts
    (``a.a.a…`` 50 000 times: a minute and 8 GiB). Brackets and braces open at once, and
    the parts of one dotted key, outside strings and comments, at most MAX_DEPTH (a float's
    one dot ends at the next comma or bracket). Raises SceneError."""
    depth = run = 0
    i, n = 0, len(text)
    while True:
        m = _SIGNIFICANT.search(text, i)
        if m is None:
            return
        i, c = m.start(), m.group()
        if c == "#":
            j = text.find("\n", i)
            i = n if j < 0 else j
            continue
        if c in "\"'":
            i = _skip_string(text, i)     # a quoted key part keeps the dotted key going
            continue
        if c == ".":
            run += 1
            if run > MAX_DEPTH:
                raise SceneError(f"a dotted key of more than {MAX_DEPTH} parts "
                                 f"({_TOO_DEEP})")
        else:
            run = 0
            if c in "[{":
                depth += 1
                if depth > MAX_DEPTH:
                    raise SceneError(_TOO_DEEP)
            elif c in "]}":
                depth = max(depth - 1, 0)
        i += 1


def _skip_string(text: str, i: int) -> int:
    """The index after the TOML string that starts at ``i`` (basic or literal, one-line or
    multi-line; an unclosed one runs to its line's or the text's end: tomllib reports it)."""
    q = text[i]
    if text.startswith(q * 3, i):
        j = i + 3
        while True:
            k = text.find(q * 3, j)
            if k < 0:
                return len(text)
            b = k
            while b > j and text[b - 1] == "\\":
                b -= 1
            escaped = q == '"' and (k - b) % 2 == 1
            if not escaped:
                while text.startswith(q, k + 3):     # up to two quotes end the content
                    k += 1
                return k + 3
            j = k + 1
    j = i + 1
    while j < len(text):
        ch = text[j]
        if ch == "\\" and q == '"':
            j += 2
            continue
        if ch == q or ch == "\n":
            return j + (ch == q)
        j += 1
    return j


def _check_depth(data, limit: int = MAX_DEPTH) -> None:
    """Nesting of tables and lists at most ``limit`` deep (without recursion); raises
    SceneError naming the key where it goes deeper."""
    stack = [(data, 0, "")]
    while stack:
        node, depth, key = stack.pop()
        if isinstance(node, (dict, list)):
            if depth > limit:
                top = re.split(r"[.\[]", key.lstrip("."), maxsplit=1)[0] or "scene"
                raise SceneError(f"{top}: {_TOO_DEEP}")
            items = node.items() if isinstance(node, dict) else enumerate(node)
            stack.extend((v, depth + 1, f"{key}.{k}" if isinstance(node, dict) else f"{key}[{k}]")
                         for k, v in items)


def json_loads(text: str):
    """``json.loads`` of input (a saved scene, a checkpoint's records) with the nesting
    bounded (MAX_DEPTH): ValueError, JSON's own error, for anything else."""
    import json
    try:
        data = json.loads(text)
    except RecursionError:
        raise ValueError(_TOO_DEEP) from None
    try:
        _check_depth(data)
    except SceneError as e:
        raise ValueError(str(e)) from None
    return data


def from_dict(cls, data: dict, path: str):
    """Build dataclass ``cls`` from a TOML table: unknown keys and wrong types are errors."""
    if not isinstance(data, dict):
        raise SceneError(f"{path or 'scene'}: expected a table, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.name != "base_dir"}
    unknown = set(data) - set(fields)
    if unknown:
        where = f"{path}." if path else ""
        raise SceneError(f"unknown key(s) {', '.join(where + k for k in sorted(unknown))} "
                         f"(allowed: {', '.join(fields)})")
    kwargs = {}
    for name, f in fields.items():
        key = f"{path}.{name}" if path else name
        if name in data:
            kwargs[name] = _convert(hints[name], data[name], key)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise SceneError(f"missing required key {key}")
    return cls(**kwargs)


def _type_name(tp) -> str:
    return getattr(tp, "__name__", str(tp)).replace("typing.", "")


def _convert(tp, value, key: str):
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (Union, types.UnionType):
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(a, value, key)
            except SceneError as e:
                errors.append(e)
        if len(errors) == 1:
            raise errors[0]
        wanted = " or ".join(_type_name(a) for a in args if a is not type(None))
        raise SceneError(f"{key} = {value!r}: expected {wanted}")
    if origin is Literal:
        if value not in args:
            raise SceneError(f"{key} = {value!r}: must be one of {', '.join(map(repr, args))}")
        return value
    if origin is list:
        if not isinstance(value, list):
            raise SceneError(f"{key}: expected a list, got {value!r}")
        return [_convert(args[0], v, f"{key}[{i}]") for i, v in enumerate(value)]
    if origin is dict:
        if not isinstance(value, dict):
            raise SceneError(f"{key}: expected a table, got {value!r}")
        return {k: _convert(args[1], v, f"{key}.{k}") for k, v in value.items()}
    if dataclasses.is_dataclass(tp):
        return from_dict(tp, value, key)
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(f"{key} = {value!r}: expected a number")
        try:
            return float(value)
        except OverflowError:   # a TOML integer of hundreds of digits
            raise SceneError(f"{key} = an integer of {len(str(abs(value)))} digits: beyond "
                             "the largest float (1.8e308)") from None
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(f"{key} = {value!r}: expected an integer")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise SceneError(f"{key} = {value!r}: expected a string")
        return value
    if tp is bool:
        if not isinstance(value, bool):
            raise SceneError(f"{key} = {value!r}: expected true or false")
        return value
    raise TypeError(f"unsupported field type {tp} at {key}")

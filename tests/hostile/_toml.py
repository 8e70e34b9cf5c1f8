"""A minimal TOML writer for the hostile cases and the property test: every table inline,
so any nesting of dicts and lists is one valid document (TOML 1.0)."""
from __future__ import annotations

import json
import math
import re

_BARE = re.compile(r"[A-Za-z0-9_-]+")


def dumps(doc: dict) -> str:
    return "".join(f"{key(k)} = {value(v)}\n" for k, v in doc.items())


def key(k: str) -> str:
    return k if _BARE.fullmatch(k) else value(k)


def value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        # JSON's escapes (\", \\, \n, \u00XX) are TOML basic-string escapes; TOML also
        # wants DEL escaped
        return json.dumps(v, ensure_ascii=False).replace("\x7f", "\\u007f")
    if isinstance(v, list):
        return "[" + ", ".join(value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{key(k)} = {value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"no TOML for {type(v).__name__}")

"""JSON that always parses, written so that a reader never sees half a file.

JSON has no NaN or infinity, and a failed fit is full of them: they are written as null. numpy
scalars and arrays become plain numbers and lists. Nothing here imports torch or numpy, so a
worker or a benchmark can use it before choosing its thread counts.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, Callable


def to_jsonable(obj: Any) -> Any:
    """obj with NaN/inf as None, tuples as lists, numpy (or torch) values as Python ones."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, (str, int)) or obj is None:  # int covers bool
        return obj
    if isinstance(obj, dict):
        return {_key(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    if hasattr(obj, "tolist") and not isinstance(obj, (bytes, bytearray)):  # numpy scalars and arrays
        return to_jsonable(obj.tolist())
    return obj


def _key(k: Any) -> str:
    # the key json.dumps would write (1 -> "1", True -> "true"), so that to_jsonable(x) is what
    # reading the file back gives; other keys (numpy numbers, tuples) would make json.dumps raise
    if isinstance(k, str):
        return k
    k = to_jsonable(k)
    if isinstance(k, (int, float)) or k is None:
        return json.dumps(k)
    return str(k)


def dumps(obj: Any, *, indent: int | None = 1, default: Callable[[Any], Any] | None = None) -> str:
    """json.dumps of to_jsonable(obj); allow_nan=False, so a NaN that slipped through raises here
    instead of writing a file no strict parser can read."""
    return json.dumps(to_jsonable(obj), indent=indent, allow_nan=False, default=default)


def write_text(text: str, path: str | Path) -> Path:
    """Write text to path through a temporary file in the same folder, renamed over it.

    A Ctrl-C or a crash mid-write leaves the old file or the new one, never half of either;
    the fsync makes the rename land after the data on a power cut too. The temporary name is
    hidden and carries the pid, so two writers of one folder do not clobber each other's.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def write_json(obj: Any, path: str | Path, *, indent: int | None = 1,
               default: Callable[[Any], Any] | None = None) -> Path:
    """dumps(obj) written atomically to path (see write_text); returns path."""
    return write_text(dumps(obj, indent=indent, default=default), path)

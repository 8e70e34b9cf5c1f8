"""Run the CLI on a disk that fills up: ``python tests/hostile/_faults.py OUT ARGS...`` runs
``fenicsx-mortar ARGS`` where, once OUT/summary.json holds a converged step, every further
write of a file under OUT fails with ENOSPC (as on a full disk; the file is created, its
bytes are not written). Python-level writes only (the fault scenes turn XDMF and plots off).
"""
from __future__ import annotations

import builtins
import errno
import io
import json
import os
import sys
from pathlib import Path

OUT = Path(sys.argv[1]).resolve()
_armed = False
_open, _fdopen, _replace = builtins.open, os.fdopen, os.replace


def _under_out(path) -> bool:
    try:
        return Path(os.path.abspath(path)).is_relative_to(OUT)
    except (TypeError, ValueError):
        return False


class _Full(io.RawIOBase):
    """A file on the full disk: writes fail."""

    def __init__(self, f):
        self._f = f

    def write(self, b):
        if _armed:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return self._f.write(b)

    def __getattr__(self, name):
        return getattr(self._f, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._f.close()

    def close(self):
        self._f.close()


def _wrap(f, path):
    return _Full(f) if _under_out(path) else f


def open_(file, *args, **kwargs):
    return _wrap(_open(file, *args, **kwargs), file)


def fdopen(fd, *args, **kwargs):
    return _wrap(_fdopen(fd, *args, **kwargs), os.readlink(f"/proc/self/fd/{fd}"))


def replace(src, dst, *args, **kwargs):
    global _armed
    _replace(src, dst, *args, **kwargs)
    if kwargs.get("dst_dir_fd") is not None:   # output.write_file: names in a directory
        dst = os.path.join(os.readlink(f"/proc/self/fd/{kwargs['dst_dir_fd']}"), dst)
    if Path(dst).resolve() == OUT / "summary.json":
        _armed = _armed or bool(json.loads(_open(dst).read()).get("steps"))


builtins.open, io.open, os.fdopen, os.replace = open_, open_, fdopen, replace

if __name__ == "__main__":
    from fenicsx_mortar.cli import main
    sys.exit(main(sys.argv[2:]))

"""A gmsh mesh file is data, never a program.

gmsh's reader is also its script interpreter: ``gmsh.open`` runs ``.geo`` files, the
``<file>.opt`` beside any file it opens, and any file whose first bytes are not a mesh
header, whatever its name (a ``System "..."`` line runs a shell command, ``Exit;`` ends the
process). So a mesh file is read here first, as bytes: a ``.msh`` name, a size limit, and
gmsh's MSH header (``$MeshFormat`` on the first line, version 2 or 4). gmsh then gets the
checked bytes through an anonymous in-memory file (:func:`open_for_gmsh`), which has no
neighbours and cannot change after the check.

No DOLFINx or gmsh import: the scene layer checks a file before anything is meshed.
"""
from __future__ import annotations

import contextlib
import os
import re
import stat
from pathlib import Path
from typing import Iterator

#: largest mesh file read (bytes): about 3x an ASCII MSH 4.1 file of the cell limit
MAX_BYTES = 512 << 20
#: suffixes gmsh treats as scripts (programs), refused by name
SCRIPTS = (".geo", ".geo_unrolled", ".opt", ".pro", ".pos", ".py")
_HEADER = re.compile(rb"\$MeshFormat\r?\n\s*(\d+)(\.\d+)?\s+([01])\s+(\d+)\s*\r?\n")


class MeshFileError(ValueError):
    """A mesh file that is not gmsh MSH data; the message names the file."""


def check(path: Path, key: str = "mesh.file") -> None:
    """Refuse ``path`` unless it is a regular ``.msh`` file within MAX_BYTES that starts
    with gmsh's MSH header (reads its first bytes only).

    Args:
        path: The mesh file.
        key: The input key named in messages.

    Raises:
        MeshFileError: naming the file and what to do.
    """
    with _opened(path, key) as (f, size):
        _check_header(f.read(256), path, key)


def read(path: Path, key: str = "mesh.file") -> bytes:
    """The bytes of a checked mesh file (see :func:`check`).

    Args:
        path: The mesh file.
        key: The input key named in messages.

    Returns:
        The file's content.

    Raises:
        MeshFileError: naming the file and what to do.
    """
    with _opened(path, key) as (f, size):
        data = f.read(MAX_BYTES + 1)
    if len(data) > MAX_BYTES:
        raise MeshFileError(f"{key}: {path} grew past {MAX_BYTES >> 20} MiB while read")
    _check_header(data[:256], path, key)
    return data


@contextlib.contextmanager
def open_for_gmsh(data: bytes) -> Iterator[str]:
    """A path gmsh can open that holds ``data`` and nothing else: an anonymous in-memory
    file (Linux memfd; no directory, so no ``.opt`` neighbour; nothing written to disk).

    Args:
        data: Checked MSH bytes (:func:`read`).

    Yields:
        The path to give ``gmsh.open``.
    """
    fd = os.memfd_create("mesh.msh", os.MFD_CLOEXEC)
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
        yield f"/proc/self/fd/{fd}"
    finally:
        os.close(fd)


@contextlib.contextmanager
def _opened(path: Path, key: str):
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in SCRIPTS:
        raise MeshFileError(
            f"{key}: {path} is a gmsh script ({suffix}): scripts are programs (they can run "
            "shell commands), and fenicsx_mortar reads mesh data only; mesh it first "
            f"(gmsh -2 {path.name} -o mesh.msh) and give the .msh file")
    if suffix != ".msh":
        raise MeshFileError(f"{key}: {path} is not a .msh file; fenicsx_mortar reads gmsh's "
                            "MSH format only (convert the mesh with gmsh and save it as .msh)")
    try:   # non-blocking: opening a FIFO would wait for a writer
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise MeshFileError(f"{key}: {path} does not exist") from None
    except IsADirectoryError:
        raise MeshFileError(f"{key}: {path} is a directory, not a gmsh mesh file") from None
    except OSError as e:
        raise MeshFileError(f"{key}: {path} cannot be read ({e.strerror})") from None
    with open(fd, "rb") as f:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise MeshFileError(f"{key}: {path} is a directory, not a gmsh mesh file")
        if not stat.S_ISREG(st.st_mode):
            raise MeshFileError(f"{key}: {path} is not a regular file (a device, FIFO or "
                                "socket)")
        if st.st_size > MAX_BYTES:
            raise MeshFileError(f"{key}: {path} has {st.st_size / 2**20:.0f} MiB, more than "
                                f"the limit of {MAX_BYTES >> 20} MiB for a mesh file")
        yield f, st.st_size


def _check_header(head: bytes, path: Path, key: str) -> None:
    m = _HEADER.match(head)
    if m is None:
        what = "is empty" if not head.strip() else "does not start with gmsh's " \
            "'$MeshFormat' header"
        raise MeshFileError(f"{key}: {path} {what}: not a gmsh MSH mesh file (fenicsx_mortar "
                            "reads MSH data only, never a script); save the mesh with gmsh "
                            "as .msh, version 2.2 or 4.1")
    major, kind, size = int(m[1]), int(m[3]), int(m[4])
    if major not in (2, 4) or size != 8:
        raise MeshFileError(f"{key}: {path} is MSH version {m[1].decode()}"
                            f"{(m[2] or b'').decode()} with data size {size}: fenicsx_mortar "
                            "reads MSH 2 and 4 with 8-byte reals (save it with gmsh as "
                            "version 4.1)")
    del kind  # ASCII (0) and binary (1) are both data

"""The DOLFINx API generations fenicsx_mortar runs on, one module each.

``v0_9`` (DOLFINx 0.9, Debian 13) is the reference: ``fenicsx_mortar/_dolfinx.py`` calls its
functions, never DOLFINx's version-specific names. ``v0_5`` (0.5.2, Debian 12), ``v0_10``
and ``v0_11`` (0.11: PyPI's ``dolfinx-solver-real``) give the same functions on their API,
each importing what did not change. A new generation is one more module with the same
``__all__`` (docs/dolfinx-versions.md lists what each changes) and one more entry in
``GENERATIONS``.
"""
from __future__ import annotations

import importlib

# (major, minor) of dolfinx.__version__ -> module
GENERATIONS = {(0, 5): "v0_5", (0, 9): "v0_9", (0, 10): "v0_10", (0, 11): "v0_11"}


def select(version: str):
    """The generation module for DOLFINx ``version``; ImportError naming what to install
    when the version is not one this package was tested on (0.6-0.8 and 0.12+ differ in
    calls we make: a silent half-working import would fail later and obscurely)."""
    try:
        key = tuple(int(p) for p in version.split(".")[:2])
    except ValueError:
        key = None
    name = GENERATIONS.get(key)
    if name is None:
        raise ImportError(
            f"fenicsx_mortar runs on DOLFINx 0.5, 0.9, 0.10 or 0.11, not {version}: install "
            "Debian 12's or Debian 13's python3-dolfinx-real, or DOLFINx 0.11 from PyPI "
            "(pip install '.[dolfinx]'; scripts/setup.sh does either: DOLFINX=apt|pip); "
            "docs/dolfinx-versions.md lists what each version changes")
    return importlib.import_module(f"{__name__}.{name}")

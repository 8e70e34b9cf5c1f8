"""Benchmarks and studies of fenicsx_mortar: scripts that measure the package, not part of it.

Run them from the repository root (``python -m benchmarks.study``, ``python
benchmarks/hertz_refinement.py``, …). Shared by them: ``analytics`` (the reference
solutions and error metrics) and ``pool`` (independent solves in worker processes).
"""

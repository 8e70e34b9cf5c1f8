"""The study's matrix: which benchmarks, methods, smoothings, enforcements and mesh levels,
the :class:`Case` of one run, and the plans (``full_plan``, ``quick_plan``)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable

from fenicsx_mortar.contact import registry

from benchmarks.analytics import HERTZ_A


METHODS = registry.METHODS.names()
SMOOTHINGS = registry.SMOOTHINGS.names()
# the study's own labels: Lagrange multipliers (semi-smooth Newton, the package default),
# penalty with epsilon = factor * E/h (slave body's E, h = slave element size in the contact
# zone), and the Uzawa ALM
ENFORCEMENTS = ("lagrange", "penalty-1", "penalty-10", "penalty-100", "alm")
BENCHMARKS = ("patch", "hertz", "hertz_mc", "half_rings")

HERTZ_REFINE_RADIUS = 0.1       # uniformly refined zone around the contact point, ~2a
# B3 shortened load path: press (t in [0, 1]) in two steps, then 12 turn steps of 0.025
RINGS_TIMES = [0.5, 1.0] + [round(1.0 + 0.025 * k, 10) for k in range(1, 13)]


@dataclass(frozen=True)
class Level:
    """One mesh size of a benchmark: a label, the slave element size h in the contact zone
    (the penalty scale E/h uses it) and the mesh generator's parameters."""
    label: str
    h: float
    params: dict


def _patch_level(n: int) -> Level:
    # upper block (slave) bottom: 2 long, 20 n elements
    return Level(f"n={n}", 2.0 / (20 * n),
                 dict(lower_nx=16 * n, lower_ny=8 * n, upper_nx=20 * n, upper_ny=4 * n))


def _hertz_level(d: int) -> Level:
    h = HERTZ_A / d
    return Level(f"a/{d}", h, dict(h_contact=h, h_far=0.1, refine_radius=HERTZ_REFINE_RADIUS))


def _rings_level(nr: int, fixed_nc: int, moving_nc: int) -> Level:
    # (4, 32, 60) is the scene's own mesh; slave = the moving ring's outer arc, r = 10
    return Level(f"{nr}x{fixed_nc}/{nr}x{moving_nc}", 10.0 * math.pi / moving_nc,
                 dict(fixed_nr=nr, fixed_nc=fixed_nc, moving_nr=nr, moving_nc=moving_nc))


LEVELS: dict[str, tuple[Level, ...]] = {
    "patch": tuple(_patch_level(n) for n in (1, 2, 3, 4)),
    "hertz": tuple(_hertz_level(d) for d in (2, 4, 8, 16)),
    "hertz_mc": tuple(_hertz_level(d) for d in (2, 4, 8, 16)),
    # levels 0-3 for the matrix, level 4 (twice the scene's mesh) for the reference only
    "half_rings": (_rings_level(2, 16, 30), _rings_level(3, 24, 44), _rings_level(4, 32, 60),
                   _rings_level(5, 40, 76), _rings_level(8, 64, 120)),
}
MATRIX_LEVELS = {"patch": (0, 1, 2, 3), "hertz": (0, 1, 2, 3), "hertz_mc": (0, 1, 2, 3),
                 "half_rings": (0, 1, 2, 3)}
RINGS_REFERENCE = ("half_rings", "mortar", "bspline", "lagrange", 4)

# the error a benchmark is ranked by (first) and the others it reports
ERRORS = {
    "patch": ("err_sigma_yy",),
    "hertz": ("err_l2", "err_p0"),
    "hertz_mc": ("err_l2", "err_p0"),
    "half_rings": ("err_reaction", "osc_reaction"),
}


@dataclass(frozen=True)
class Case:
    benchmark: str
    method: str
    smoothing: str
    enforcement: str
    level: int

    @property
    def key(self) -> tuple:
        return (self.benchmark, self.method, self.smoothing, self.enforcement, self.level)

    def describe(self) -> str:
        return (f"{self.benchmark} {self.method} {self.smoothing} {self.enforcement} "
                f"{LEVELS[self.benchmark][self.level].label}")


@dataclass
class Plan:
    """The cases to run, the per-run limits and what the report says was left out.

    ``skip_after``: a case is not run (recorded as "skipped") when the same combination did
    not converge at the ``skip_after`` next coarser levels of the plan (0: run everything).
    ``reference``: the B3 reference case (never skipped; its CPU limit is
    ``reference_limit_factor`` times the others')."""
    name: str
    cases: list[Case]
    cpu_limit: float = 120.0           # seconds of the worker's CPU time per run
    wall_limit: float = 600.0          # backstop on wall time per run
    left_out: list[str] = field(default_factory=list)
    skip_after: int = 2
    reference: Case | None = None
    reference_limit_factor: float = 4.0


def matrix(benchmarks: Iterable[str] = BENCHMARKS, methods: Iterable[str] = METHODS,
           smoothings: Iterable[str] = SMOOTHINGS, enforcements: Iterable[str] = ENFORCEMENTS,
           levels: dict[str, Iterable[int]] | Iterable[int] | None = None) -> list[Case]:
    """Every combination; ``levels`` as indices into LEVELS[benchmark] (one list for all
    benchmarks or a dict per benchmark; default MATRIX_LEVELS)."""
    out = []
    for b in benchmarks:
        if levels is None:
            lv = MATRIX_LEVELS[b]
        elif isinstance(levels, dict):
            lv = levels.get(b, ())
        else:
            lv = levels
        for m in methods:
            for s in smoothings:
                for e in enforcements:
                    for k in lv:
                        out.append(Case(b, m, s, e, int(k)))
    return out


def reference_case(cases: Iterable[Case]) -> Case | None:
    """B3 reference: the finest-level bspline + mortar + lagrange run among ``cases``."""
    rings = [c for c in cases if c.benchmark == "half_rings" and c.method == "mortar"
             and c.smoothing == "bspline" and c.enforcement == "lagrange"]
    return max(rings, key=lambda c: c.level, default=None)


def make_plan(name: str, cases: list[Case], **kw) -> Plan:
    """A plan whose B3 reference is the finest bspline + mortar + lagrange case in it."""
    return Plan(name, cases, reference=reference_case(cases), **kw)


def full_plan() -> Plan:
    """The documented matrix (2 x 6 x 4 x 4 levels per benchmark), with the reductions
    listed in ``left_out``, and the B3 reference on a mesh twice the scene's."""
    cases = [c for c in matrix() if not (c.smoothing == "averaged-tangent" and c.level > 0)]
    cases.append(Case(*RINGS_REFERENCE))
    return make_plan("full", cases, cpu_limit=120.0, wall_limit=600.0, left_out=[
        "`averaged-tangent` is run at the coarsest level only: in 2D its nodal normal is "
        "that of `averaged-simple` (docs/smoothing.md), and the level-0 runs show the same "
        "errors (table below); at the finer levels its results would repeat "
        "`averaged-simple`'s",
        "a combination that did not converge at the two next coarser levels is not run at a "
        "finer one (status `skipped` in the CSV and the tables)",
        "B3 uses a shortened load path (press, then 30 % of the scene's turn), and its finest "
        "mesh (8x64/8x120, twice the scene's) only for the reference run"])


def quick_plan() -> Plan:
    """A few minutes: the two coarsest levels, two smoothings, two enforcements."""
    cases = matrix(smoothings=("none", "bspline"), enforcements=("lagrange", "penalty-1", "alm"),
                   levels=(0, 1))
    return make_plan("quick", cases, cpu_limit=30.0, wall_limit=120.0, left_out=[
        "levels: only the two coarsest of each benchmark (B3 reference: bspline + mortar + "
        "lagrange at the second level)",
        "smoothings: only `none` and `bspline`",
        "enforcements: only `lagrange`, `penalty-1` and `alm`"])

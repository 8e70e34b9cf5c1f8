"""The hard cases of the stability suite: scenes, bounds, cached runs (docs/stability.md).

``RUNS`` maps a run label to its scene file; ``BOUNDS`` gives each label's Newton-iteration
bound (per step, summed over the ALM augmentations of the step) and step-cut bound (failed
attempts over the whole run). ``get(label)`` solves a scene once per process.
"""
from __future__ import annotations

import functools

from _common import HARD, Run, run_scene

from fenicsx_mortar.contact.registry import SMOOTHINGS as _REGISTRY

SMOOTHINGS = _REGISTRY.names()

RUNS = {
    "1 grazing": "c01_grazing_approach.toml",
    "2a ties on nodes": "c02a_ties_on_nodes.toml",
    "2b ties on nodes+midpoints": "c02b_ties_on_nodes_and_midpoints.toml",
    "2c slave beyond master": "c02c_slave_beyond_master.toml",
    **{f"3 half-rings {s}": f"c03_half_rings_{s}.toml" for s in SMOOTHINGS},
    "4 stick-slip-stick": "c04_stick_slip_stick_reversal.toml",
    "5 lift-off/re-contact": "c05_liftoff_recontact.toml",
    "6a huge eps, ALM": "c06a_huge_penalty_alm.toml",
    "6b huge eps, penalty": "c06b_huge_penalty_penalty.toml",
    "7 initial penetration": "c07_initial_penetration.toml",
    "8a ratio 1:10 slave fine": "c08a_density_ratio.toml",
    "8b ratio 1:10 slave coarse": "c08b_density_ratio.toml",
    "9a mu = 1.0": "c09a_high_friction.toml",
    "9b mu = 1e-6": "c09b_vanishing_friction.toml",
    "10 active-set cycling": "c10_active_set_cycling.toml",
    "11 touching, huge R0": "c11_touching_huge_residual.toml",
    "12 stiff slave, press + slide": "c12_stiff_slave_press_and_slide.toml",
    "13 half-rings, finer master": "c13_half_rings_finer_master.toml",
}

# (max Newton iterations in one step, max step cuts in the run), about 1.5x what a healthy
# run of the package needed when the suite was written
BOUNDS = {
    "1 grazing": (40, 1),
    "2a ties on nodes": (30, 0),
    "2b ties on nodes+midpoints": (40, 0),
    "2c slave beyond master": (60, 1),
    **{f"3 half-rings {s}": (80, 2) for s in SMOOTHINGS},
    "4 stick-slip-stick": (36, 0),
    "5 lift-off/re-contact": (40, 1),
    "6a huge eps, ALM": (30, 0),
    "6b huge eps, penalty": (25, 1),
    "7 initial penetration": (30, 0),
    "8a ratio 1:10 slave fine": (20, 0),
    "8b ratio 1:10 slave coarse": (20, 0),
    "9a mu = 1.0": (36, 0),
    "9b mu = 1e-6": (36, 0),
    "10 active-set cycling": (25, 0),
    "11 touching, huge R0": (25, 0),
    # semi-smooth Newton with multipliers: the active and stick/slip sets settle within
    # each Newton solve (5-7 iterations a step), never by a step cut
    "12 stiff slave, press + slide": (12, 0),
    # two weak slave nodes side by side at the master's end hand over to the supported one
    "13 half-rings, finer master": (10, 0),
}

LOGS: dict[str, list[str]] = {}


@functools.lru_cache(maxsize=None)
def get(label: str) -> Run:
    log = LOGS.setdefault(label, [])
    return run_scene(HARD / RUNS[label], name=label, log=log.append)

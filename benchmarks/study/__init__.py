"""Accuracy against compute time: ``python -m benchmarks.study [--quick] [--out DIR] [--jobs N]``
from the repository root (or ``fenicsx-mortar study`` in a source checkout).

A thin driver around :func:`fenicsx_mortar.solve`. It runs the matrix

    method (nts, mortar) x smoothing (six) x enforcement (penalty at 1, 10, 100 x E/h; alm)
    x mesh level (four per benchmark)

on four benchmarks built from the demo scenes by changing dataclass fields (``scenes``):

* ``patch``       B1 contact patch test (``demos/scenes/patch_test.toml``), error
                  max over cells of |sigma_yy + 1|;
* ``hertz``       B2 Hertz, slave = the disk's arc, master = the block's flat top
                  (``demos/scenes/hertz.toml``), errors |p_max/p0 - 1| and the relative L2
                  error of the nodal pressure on [-a, a] (``benchmarks/analytics.py``);
* ``hertz_mc``    the same with the roles swapped: master = the curved arc (so the master
                  smoothing acts on a curved surface), slave = the block's top;
* ``half_rings``  B3 frictionless half-rings on a shortened load path (press in two steps,
                  then the turn up to t = 1.3 in steps of 0.025, i.e. 30 % of the scene's
                  turn); errors: the hub reaction curve against the reference (the bspline +
                  mortar + alm run on a mesh twice the scene's) and its oscillation.

E/h: the slave body's Young's modulus over the slave element size in the contact zone
(``Level.h``). Step control is the scene's, with a floor at 1/16 of its smallest increment.

The full plan (``cases.full_plan``) leaves out what would only repeat other runs and what has
already failed: averaged-tangent runs at the coarsest level only (in 2D its nodal normal is
averaged-simple's), and a combination that did not converge at the two next coarser levels
is recorded as "skipped" at the finer ones. It takes about 40 min on two shared cores;
``--quick`` (``cases.quick_plan``) a few minutes.

Every run happens in a worker process of ``benchmarks.pool`` (``--jobs`` of them, each
single-threaded), so a run that crashes or exceeds the per-run CPU limit is recorded as such
and the study goes on. Per run it records the errors, process CPU time, wall time in total
and by phase (``Result.timings``), Newton iterations, augmentations, cuts and the solver's
message.

Outputs, in ``--out`` (default: the repository's ``docs/``; ``--quick``: ``results/study_quick``):
``accuracy-vs-time.md`` (tables), ``study/runs.csv`` (one row per run),
``study/reaction_curves.json`` (B3 curves), ``study/meta.json`` (command, duration, load,
environment), ``study/pareto_<benchmark>.png`` (error against CPU time, log-log, one curve
per method/smoothing). When ``--out`` is the repository's ``docs/``, the headline table in
README.md (between the ``study-headline`` markers) is regenerated too. ``--report-only``
rewrites tables and plots from an existing CSV.

Modules, one job each: ``cases`` (the matrix and the plans), ``scenes`` (the scene of a
case), ``runner`` (one run in a worker, the plan on the pool, the outputs), ``metrics``
(the errors of a run), ``records`` (the CSV), ``report``, ``observations``, ``tables`` and
``plots`` (the document and its figures), ``__main__`` (the command line).
"""

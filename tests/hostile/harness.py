"""Running a hostile case in a subprocess (or under mpirun) and sorting what came out.

The kinds of outcome, in the order they are decided: ``hung`` (killed at the time limit),
``wrote outside --out``, ``crashed`` (a traceback, or killed by a signal: segfault, abort,
a bare SIGTERM), ``wrong exit 0`` / ``ignored silently`` / ``accepted unchecked`` (exit 0
where the case must fail, its ``hazard`` says which: a wrong answer; the value had no
effect; a value unbounded in memory or time, an unsafe name or an unverifiable file taken
as it came, with a right answer this time), ``refused, key not named`` / ``stopped, key
not named`` (exit 2 or 1 without the key or file at fault in the message, e.g. a Newton
failure), ``refused as expected``, ``stopped as expected``, ``ran as expected``;
``other`` for anything else (e.g. the right exit code but a failed extra check).
"""
from __future__ import annotations

import os
import re
import resource
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .cases import DONORS, Case, unmount
from ._toml import dumps

MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1"}
#: the kind of an exit 0 where the case must fail, by its hazard
EXIT_0 = {"wrong": "wrong exit 0", "ignored": "ignored silently",
          "unchecked": "accepted unchecked"}
#: a case's own JIT cache (XDG_CACHE_HOME), not an output
JIT_CACHE = "jit-cache"
GOOD = ("refused as expected", "stopped as expected", "ran as expected")


@dataclass
class Outcome:
    code: int | None          # None: killed at the time limit
    out: str
    err: str
    seconds: float
    stray: list[str]
    dir: Path
    problem: str = ""         # what the case's check found wrong


class Donors:
    """Finished runs the restart cases copy, made once (with the code under test)."""

    def __init__(self, root: Path, env: dict | None = None):
        self.root, self.env, self._done = root, env, {}

    def get(self, name: str) -> Path:
        if name not in self._done:
            d = self.root / name
            d.mkdir(parents=True, exist_ok=True)
            (d / "scene.toml").write_text(dumps(DONORS[name]))
            proc = self.run_in(d, "run", str(d / "scene.toml"), "--out", str(d / "out"))
            assert proc.returncode == 0, proc.stderr[-2000:]
            self._done[name] = d / "out"
        return self._done[name]

    def run_in(self, d: Path, *argv: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "fenicsx_mortar", *argv], cwd=d,
                              capture_output=True, text=True, timeout=300,
                              env=self.env or os.environ)


def files_under(d: Path) -> set[str]:
    return {str(p.relative_to(d)) for p in d.rglob("*")} if d.exists() else set()


def stray(d: Path, before: set[str]) -> list[str]:
    """Files that appeared in D but not under D/out (the only place a run may write)."""
    return sorted(f for f in files_under(d) - before
                  if not (f in ("out", JIT_CACHE) or f.startswith(("out/", JIT_CACHE + "/"))))


def command(case: Case, d: Path) -> list[str]:
    cmd = [sys.executable]
    if case.fault:
        cmd += [str(Path(__file__).parent / "_faults.py"), str(d / "out")]
    else:
        cmd += ["-m", "fenicsx_mortar"]
    cmd += case.args(d)
    if case.mode == "mpi":
        from fenicsx_mortar.mpi_launch import mpi_command
        cmd = [*mpi_command(case.ranks), *cmd]
    return cmd


def _limit_memory() -> None:
    """8 GiB of address space per process: a case that reads /dev/zero on a version of the
    code without the guard must not take the (shared) machine down."""
    resource.setrlimit(resource.RLIMIT_AS, (8 << 30, 8 << 30))


def run_process(case: Case, d: Path, donors: Donors, env: dict | None = None,
                timeout: float | None = None) -> Outcome:
    """Lay the case out in ``d`` and run it as a process (``env``: e.g. PYTHONPATH of the
    code under test); the time limit kills the whole process group."""
    case.write_inputs(d, donors)
    before = files_under(d)
    env = {**(env or os.environ), **MPI_ENV, "PYTHONUNBUFFERED": "1",
           **{k: v if v is None else v.format(dir=d) for k, v in case.env.items()}}
    env = {k: v for k, v in env.items() if v is not None}      # None: unset
    # a case's stdout may be a file (/dev/full: every write fails)
    stdout = open(case.stdout, "w") if case.stdout else subprocess.PIPE
    t0 = time.time()
    try:
        proc = subprocess.Popen(command(case, d), cwd=d / "work", env=env, text=True,
                                stdout=stdout, stderr=subprocess.PIPE,
                                start_new_session=True, preexec_fn=_limit_memory)
    finally:
        if case.stdout:
            stdout.close()
    seen = ""
    try:
        if case.sender is not None:
            case.sender(proc, d)
            seen = getattr(proc, "seen", "")
        out, err = proc.communicate(timeout=timeout or case.timeout)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        out, err = proc.communicate()
        code = None
    out = out or ""
    try:
        o = Outcome(code, seen + out, err, time.time() - t0, stray(d, before), d)
        o.problem = problem(case, o)
    finally:
        unmount(d)
    return o


def problem(case: Case, o: Outcome) -> str:
    """What the case's extra check finds wrong ("" if nothing, or no check to make)."""
    if case.check is None or o.code != case.expect:
        return ""
    try:
        return case.check(o.dir, o.out, ours(o.err))
    except Exception as e:  # the outputs the check reads are missing or broken
        return f"{type(e).__name__}: {e}"


def ours(err: str) -> str:
    """stderr without Open MPI's own reports (of a non-zero exit, of MPI_Abort): its blocks
    between dashed lines, its "[host:pid] ..." help-aggregation lines and its components'
    lines ("mca_fbtl_posix_pwritev: error in (p)write(v): ..." on a full disk); and without
    MPICH's line for MPI_Abort ("Abort(1) on node 0 (rank 0 in comm 0): ...") and the
    copy of the aborting rank's last line that MPICH's launcher sometimes forwards again
    with it (seen with mpiexec -prepend-rank: both from rank 0, written once); and the text
    of rank 0's last stdout log line that Open MPI 5 sometimes forwards on stderr, without
    its newline, in front of the error line of an aborting run (seen on Debian 13:
    "  warning: body ...(a singular stiffness)fenicsx-mortar: error: ...", the warning
    missing from stdout)."""
    kept, inside, aborted = [], False, False
    for line in err.splitlines(keepends=True):
        ours_at = line.find("fenicsx-mortar: ")
        if ours_at > 0 and line.startswith("  "):      # the runner's log lines are indented
            line = line[ours_at:]
        if line.startswith("-----"):
            inside = not inside
        elif re.match(r"Abort\(\d+\) on node \d+ ", line):
            aborted = True
        elif not inside and not re.match(r"\[[^\]\s]+:\d+\] |mca_\w+: ", line) \
                and not (aborted and line in kept):
            kept.append(line)
    return "".join(kept)


def kind(case: Case, o: Outcome) -> str:
    """The kind of outcome (module docstring)."""
    if o.code is None:
        return "hung"
    if o.stray:
        return "wrote outside --out"
    if "Traceback" in o.err or "Traceback" in o.out or o.code not in (0, 1, 2):
        return "crashed"
    problem = o.problem
    if o.code == 0:
        if case.expect == 0 and not problem:
            return "ran as expected"
        return EXIT_0[case.hazard]
    err = ours(o.err)
    message = err if o.code == 2 else err + o.out
    named = case.key in message
    if o.code == 2:
        one_line = err.startswith("fenicsx-mortar: error:") and err.count("\n") == 1
        if not named:
            return "refused, key not named"
        if case.expect == 2 and one_line and not problem:
            return "refused as expected"
        return "other"
    if not named:
        return "stopped, key not named"
    return "stopped as expected" if case.expect == 1 and not problem else "other"


def fresh(d: Path) -> Path:
    if d.exists():
        unmount(d)
        shutil.rmtree(d)
    d.mkdir(parents=True)
    return d

"""One process pool for the benchmarks: independent solves in worker processes, one core
each, every job under a CPU-time and a wall-time limit.

Workers are plain subprocesses, ``python -m benchmarks.pool --worker FD TARGET [WARM_UP]``
(TARGET and WARM_UP as ``module:function``): the first line on a worker's stdin is the
warm-up's argument, then one job per line, all JSON; TARGET's dict for each job comes back
as a JSON line on the pipe FD, while the worker's stdout and stderr (the package's and
PETSc's prints) go wherever the caller says. So nothing needs a ``__main__`` guard in the
caller, and a worker that crashes takes only its current job with it.

A job over its CPU limit (the worker process's user + system time) or its wall limit gets
SIGTERM: inside ``fenicsx_mortar.solve``'s Newton loop the solver turns it into a clean stop
(a result that says "interrupted by SIGTERM"), elsewhere during a job it raises
:class:`TimeLimit`; a worker that has not answered 60 s later is killed and replaced.
"""
from __future__ import annotations

import importlib
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Callable, Iterable

ROOT = Path(__file__).resolve().parents[1]

# one thread per worker: the workers are the parallelism
SINGLE_THREAD = {v: "1" for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
KILL_AFTER = 60.0                       # seconds between SIGTERM and SIGKILL
RESEND_AFTER = 1.0                      # seconds between SIGTERMs to a job still running


def blas_in_use() -> str:
    """The BLAS library this process has loaded (MUMPS's factorization runs on it: Debian's
    reference BLAS is ≈ 1.5× slower there than OpenBLAS, docs/performance.md), from
    /proc/self/maps; call it after PETSc is loaded."""
    try:
        maps = Path("/proc/self/maps").read_text().split()
    except OSError:
        return "unknown"
    names = ("libblas.", "libopenblas", "libmkl_rt", "libblis")
    libs = sorted({m for m in maps if m.startswith("/") and Path(m).name.startswith(names)})
    return ", ".join(libs) or "none loaded"


class TimeLimit(BaseException):
    """Raised in a worker by SIGTERM outside the solver's Newton loop (a BaseException, so
    that no ``except Exception`` on the way swallows it)."""


@dataclass
class Job:
    """One call of the pool's target: ``payload`` (JSON) is sent to the worker, ``tag``
    stays with the caller (what the job is, for ``on_done``)."""
    payload: Any
    cpu_limit: float = float("inf")
    wall_limit: float = float("inf")
    tag: Any = None


@dataclass
class Outcome:
    """A finished job: the target's dict, or None when the worker died first (then
    ``returncode`` says how); ``stopped`` when the pool had signalled the time limit."""
    job: Job
    record: dict | None
    stopped: bool
    returncode: int | None
    wall: float                         # seconds from sending the job to its end


def _resolve(target: str) -> Callable:
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


def worker_main(fd: int, target: str, warm_up: str | None = None) -> None:
    """A worker: the first line on stdin is ``warm_up``'s argument, then one job per line
    until EOF; one JSON line per job is written to ``fd``."""
    # SIGTERM = the parent's time limit; between jobs it is ignored
    busy = [False]

    def on_term(*args):
        if busy[0]:
            raise TimeLimit("stopped by the study's time limit")
    signal.signal(signal.SIGTERM, on_term)
    out = os.fdopen(fd, "w")
    fn = _resolve(target)
    first = json.loads(sys.stdin.readline())
    if warm_up is not None:     # JIT-compiled forms and lazy imports out of the timed jobs
        _resolve(warm_up)(first)
    out.write('"ready"\n')
    out.flush()
    for line in sys.stdin:
        if not line.strip():
            continue
        busy[0] = True
        try:
            rec = fn(json.loads(line))
        finally:
            busy[0] = False
        out.write(json.dumps(rec, default=str) + "\n")
        out.flush()


class _Worker:
    def __init__(self, target: str, warm_up: str | None, warm_up_arg: Any, output):
        r, w = os.pipe()
        # the worker imports ``benchmarks`` from this checkout, whatever its cwd
        path = os.pathsep.join([str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
        env = {**os.environ, **SINGLE_THREAD, "PYTHONPATH": path}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "benchmarks.pool", "--worker", str(w), target]
            + ([warm_up] if warm_up else []),
            stdin=subprocess.PIPE, stdout=output, stderr=output, pass_fds=(w,), env=env,
            text=True)
        os.close(w)
        os.set_blocking(r, False)
        self.fd, self.buf = r, b""
        self.send(json.dumps(warm_up_arg))
        self.ready = False
        self.job: Job | None = None
        self.t0 = self.cpu0 = 0.0
        self.terminated_at: float | None = None
        self.signalled_at = 0.0

    def send(self, line: str) -> None:
        try:
            self.proc.stdin.write(line + "\n")
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            pass

    def start(self, job: Job) -> None:
        self.job = job
        self.t0, self.cpu0 = time.perf_counter(), self.cpu()
        self.send(json.dumps(job.payload))

    def messages(self) -> list:
        """Complete JSON lines received so far."""
        try:
            while True:
                chunk = os.read(self.fd, 1 << 16)
                if not chunk:
                    break
                self.buf += chunk
        except BlockingIOError:
            pass
        *lines, self.buf = self.buf.split(b"\n")
        return [json.loads(x) for x in lines if x.strip()]

    def alive(self) -> bool:
        return self.proc.poll() is None

    def cpu(self) -> float:
        return process_cpu(self.proc.pid)

    def close(self) -> None:
        try:
            self.proc.stdin.close()
        except OSError:
            pass
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self.fd)


def process_cpu(pid: int) -> float:
    """User + system CPU seconds of a process (Linux /proc)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


def run(target: str, jobs: Iterable[Job | None], on_done: Callable[[Outcome], None],
        workers: int = 1, warm_up: str | None = None, warm_up_arg: Any = None,
        output: IO | int | None = subprocess.DEVNULL) -> None:
    """Run ``target`` on every job of ``jobs`` in ``workers`` processes; ``on_done`` gets
    each outcome as it comes. ``jobs`` is drawn from whenever a worker is free, so it may be
    a generator that decides what to run from the outcomes so far: a None from it means
    "nothing to start yet" (it is asked again later). ``output``: where the workers' stdout
    and stderr go, as ``subprocess.Popen`` takes it (None: this process's)."""
    queue = iter(jobs)
    exhausted = False

    def start() -> _Worker:
        return _Worker(target, warm_up, warm_up_arg, output)

    def finish(w: _Worker, record: dict | None) -> None:
        job, stopped = w.job, w.terminated_at is not None
        w.job, w.terminated_at = None, None
        on_done(Outcome(job, record, stopped, w.proc.returncode, time.perf_counter() - w.t0))

    pool = [start() for _ in range(max(1, workers))]
    deaths_before_ready = 0
    try:
        while not exhausted or any(w.job is not None for w in pool):
            for i, w in enumerate(pool):
                for msg in w.messages():
                    if msg == "ready":
                        w.ready = True
                    elif w.job is not None:
                        finish(w, msg)
                if not w.alive():
                    for msg in w.messages():
                        if w.job is not None and msg != "ready":
                            finish(w, msg)
                    if w.job is not None:
                        finish(w, None)
                    if not w.ready:
                        deaths_before_ready += 1
                        if deaths_before_ready > 3:
                            raise RuntimeError(
                                "pool workers die before they are ready: run `python -m "
                                f"benchmarks.pool --worker 1 {target}` to see why")
                    w.close()
                    pool[i] = w = start()
                if w.ready and w.job is None and not exhausted:
                    job = next(queue, StopIteration)
                    if job is StopIteration:
                        exhausted = True
                    elif job is not None:
                        w.start(job)
                if w.job is not None:
                    now = time.perf_counter()
                    over = (w.cpu() - w.cpu0 > w.job.cpu_limit or now - w.t0 > w.job.wall_limit)
                    if over and w.terminated_at is None:
                        w.terminated_at = w.signalled_at = now
                        w.proc.send_signal(signal.SIGTERM)
                    elif w.terminated_at is not None and now - w.terminated_at > KILL_AFTER:
                        w.proc.kill()
                        w.proc.wait()
                    elif w.terminated_at is not None and now - w.signalled_at > RESEND_AFTER:
                        # a worker ignores SIGTERM between jobs: one that came while it was
                        # still clearing up the previous job (its CPU counts from the start)
                        # was lost (seen with a 0.01 s limit: the job then ran to the end)
                        w.signalled_at = now
                        w.proc.send_signal(signal.SIGTERM)
            time.sleep(0.05)
    finally:
        for w in pool:
            w.close()


if __name__ == "__main__":
    if len(sys.argv) in (4, 5) and sys.argv[1] == "--worker":
        # through the imported module, not this __main__ copy: the targets catch
        # benchmarks.pool.TimeLimit, which must be the class the handler raises
        from benchmarks.pool import worker_main as _main
        _main(int(sys.argv[2]), *sys.argv[3:])
    else:
        sys.exit(f"usage: python -m benchmarks.pool --worker FD module:function "
                 f"[module:warm_up]\n{__doc__}")

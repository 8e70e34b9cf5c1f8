"""Command line: ``fenicsx-mortar run SCENE.toml --out DIR``, ``fenicsx-mortar check
SCENE.toml``, and in a source checkout ``fenicsx-mortar study [--quick] [--out DIR]``
(``python -m benchmarks.study``, docs/accuracy-vs-time.md).

Exit codes: 0 converged, 1 the run stopped early (outputs up to the last converged step are
kept) or the environment does not let it start (an unusable JIT cache), 2 bad input (one
message naming the problem, no traceback).

The environment is not input: PETSc options come from the scene's ``solver.petsc`` only
(checked there), so ``PETSC_OPTIONS``, ``PETSC_OPTIONS_YAML`` and ``.petscrc`` files are
ignored, with a warning. A broken stdout or stderr (a closed pipe, a full disk) costs the
log lines only, never the outputs; text the stream's encoding cannot take is escaped.
"""
from __future__ import annotations

import argparse
import contextlib
import errno
import io
import os
import re
import signal
import sys
import threading
from pathlib import Path

#: PETSc reads options from these variables at start-up; the run ignores them
PETSC_VARIABLES = ("PETSC_OPTIONS", "PETSC_OPTIONS_YAML")
#: JIT settings DOLFINx and FFCx read from the working directory (0.5 and 0.9 names)
JIT_SETTINGS_FILES = ("dolfinx_jit_parameters.json", "dolfinx_jit_options.json",
                      "ffcx_parameters.json", "ffcx_options.json")


class _Parser(argparse.ArgumentParser):
    """argparse, with a usage error as the one line every other error is (and from the
    first MPI rank only; MPI is not started yet here)."""

    def error(self, message: str):
        import os
        if os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK", "0")) == "0":
            _say(f"fenicsx-mortar: error: {self.prog}: {message} (see fenicsx-mortar --help)")
        sys.exit(2)


def _directory(text: str) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty name (the outputs would go into the "
                                         "working directory; give a directory)")
    try:
        os.stat(text)
    except OSError as e:
        if e.errno == errno.ENAMETOOLONG:
            raise argparse.ArgumentTypeError("the file name is too long for the file "
                                             "system") from None
    return Path(text)


def main(argv: list[str] | None = None) -> int:
    """The command line (module docstring); returns the exit code."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["study"]:
        return _study(argv[1:])
    ignored = _ignore_petsc_environment()
    with _tolerant_streams():
        return _main(argv, ignored)


def _main(argv: list[str], ignored: list[str]) -> int:
    parser = _Parser(prog="fenicsx-mortar",
                     description="2D finite-deformation mortar contact on FEniCSx")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scene file")
    run.add_argument("scene", type=Path, nargs="?", help="scene file (TOML, see docs/scenes.md)")
    run.add_argument("--out", type=_directory, default=None,
                     help="output directory (default: results/<scene name>)")
    run.add_argument("--restart", type=_directory, default=None, metavar="DIR",
                     help="continue the run in DIR from its last converged step")
    check = sub.add_parser("check", help="validate a scene file (and its mesh) without solving")
    check.add_argument("scene", type=Path)
    # listed for --help only: main() hands "study" to the study's own parser first
    sub.add_parser("study", add_help=False, help="accuracy against compute time: method x "
                   "smoothing x enforcement x mesh size on B1-B3 (source checkout only; "
                   "docs/accuracy-vs-time.md)")
    args = parser.parse_args(argv)
    with _Interrupt():
        return _command(args, ignored)


def _ignore_petsc_environment() -> list[str]:
    """Keep PETSc from reading options outside the scene, before it starts: the variables
    are removed from this process's environment and the option files skipped
    (``-skip_petscrc``); a viewer there could write anywhere (``-log_view :../x``) and
    nothing would check it. Also no PETSc handler for SIGPIPE: a closed stdout would end
    the run with a signal dump (Python then sees EPIPE, which the streams absorb).
    Returns what was set and is ignored, for the warning."""
    ignored = [v for v in PETSC_VARIABLES if os.environ.pop(v, "").strip()]
    for place in (Path.cwd(), Path.home() if "HOME" in os.environ else None):
        for name in (".petscrc", "petscrc"):
            with contextlib.suppress(OSError, RuntimeError):
                if place is not None and (place / name).is_file():
                    ignored.append(str(place / name))
    from mpi4py import MPI  # noqa: F401  (MPI first, with its thread level, as before)
    if "petsc4py.PETSc" not in sys.modules:
        import petsc4py
        petsc4py.init([sys.argv[0] if sys.argv and sys.argv[0] else "fenicsx-mortar",
                       "-skip_petscrc"])
    from petsc4py import PETSc  # noqa: F401  (PETSc starts here, with those arguments)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGPIPE, signal.SIG_IGN)
    return ignored


class _TolerantStream(io.TextIOBase):
    """stdout or stderr that never stops the run: a write that fails (EPIPE after ``|
    head``, ENOSPC on /dev/full) drops this and every later line of the stream, and text
    the stream's encoding cannot take (PYTHONIOENCODING=ascii, a non-ASCII title) is
    escaped (backslashreplace)."""

    def __init__(self, stream):
        self._stream, self.broken = stream, False

    def write(self, s: str) -> int:
        if not self.broken:
            try:
                self._stream.write(s)
            except UnicodeEncodeError:
                enc = getattr(self._stream, "encoding", None) or "ascii"
                self._guard(lambda: self._stream.write(
                    s.encode(enc, "backslashreplace").decode(enc, "replace")))
            except (OSError, ValueError):
                self._break()
        return len(s)

    def _guard(self, call) -> None:
        try:
            call()
        except (OSError, ValueError, UnicodeError):
            self._break()

    def _break(self) -> None:
        """From now on the stream's file descriptor writes to /dev/null: what is still
        buffered, C libraries' own writes and Python's flush at exit then succeed (a
        failed flush at exit is a message and exit code 120)."""
        self.broken = True
        with contextlib.suppress(OSError, ValueError, io.UnsupportedOperation):
            fd = self._stream.fileno()
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, fd)
            os.close(null)

    def flush(self) -> None:
        if not self.broken:
            self._guard(self._stream.flush)

    def isatty(self) -> bool:
        return not self.broken and self._stream.isatty()

    def fileno(self) -> int:
        return self._stream.fileno()

    def writable(self) -> bool:
        return True

    @property
    def encoding(self):
        return getattr(self._stream, "encoding", None)

    @property
    def buffer(self):
        return self._stream.buffer

    @property
    def errors(self):
        return "backslashreplace"


@contextlib.contextmanager
def _tolerant_streams():
    """sys.stdout and sys.stderr as :class:`_TolerantStream` for the command; after it the
    originals, flushed quietly (Python would report a failed flush at exit, with code
    120)."""
    old = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = (_TolerantStream(f) if f is not None else None for f in old)
    try:
        yield
    finally:
        for f in (sys.stdout, sys.stderr):
            if f is not None:
                f.flush()
        sys.stdout, sys.stderr = old
        for f in old:
            with contextlib.suppress(OSError, ValueError):
                if f is not None:
                    f.flush()


def _command(args, ignored: list[str] = ()) -> int:
    """Run the command; every anticipated failure is one line on stderr (rank 0) and the
    same exit code on every rank: 2 bad input, 1 the run stopped (RunError: a write
    failed, a signal outside the load steps). Anything else under MPI ends all ranks
    (MPI_Abort) instead of leaving them waiting for the one that failed."""
    from mpi4py import MPI

    from .scene.parallel import BrokenOutput, Interrupted, RunError
    from .scene import SceneError
    comm = MPI.COMM_WORLD
    if ignored and comm.rank == 0:
        _say(f"fenicsx-mortar: warning: {', '.join(ignored)} ignored: PETSc options come from "
             "the scene's solver.petsc only, where they are checked")
    try:
        return _dispatch(args, comm)
    except (Interrupted, BrokenOutput) as e:
        # raised where each rank was (the signal) or on the ranks whose HDF5 write failed,
        # while the others may wait in a collective call: end them all
        if comm.size > 1:
            _abort_all(comm, e)
        _error(comm, e)
        return 1
    except SceneError as e:
        _error(comm, e)
        return 2
    except RunError as e:
        _error(comm, e)
        return 1
    except Exception as e:
        jit = _jit_failure(e)
        if jit is not None:
            _error(comm, jit)
            return 1
        if comm.size > 1:
            import traceback
            traceback.print_exc()
            sys.stderr.flush()
            comm.Abort(1)
        raise


def _dispatch(args, comm) -> int:
    from .scene.guards import check_petsc_options
    from .scene import SceneError, load_scene, load_scene_json
    if args.command == "run" and args.restart is not None:
        if args.scene is not None:
            raise SceneError(f"--restart {args.restart}: continues with "
                             f"{args.restart / 'scene.json'}; give no scene file "
                             f"(got {args.scene})")
        if args.out is not None and args.out.resolve() != args.restart.resolve():
            raise SceneError(f"--out {args.out}: a restart writes to its own directory "
                             f"{args.restart}; give no --out")
        if not args.restart.is_dir():
            raise SceneError(f"--restart {args.restart}: not a directory of a run")
        scene = load_scene_json(args.restart / "scene.json")
        args.scene, args.out = args.restart / "scene.json", args.restart
    elif args.scene is None:
        raise SceneError("run: give a scene file (or --restart DIR)")
    else:
        scene = load_scene(args.scene)
    if args.command == "check":
        from .scene.meshing import build_domain
        check_petsc_options(scene.solver)
        dom = build_domain(scene, comm)
        if comm.rank == 0:
            for w in dom.warnings:
                print(f"{args.scene}: warning: {w}")
            print(f"{args.scene}: OK")
        return 0
    from .scene.runner import solve

    def show_warning(message, category, filename, lineno, file=None, line=None):
        # one line, from rank 0 (a library import routes warnings through logging, which
        # printed two lines with the source line of the call)
        if comm.rank == 0:
            _say(f"fenicsx-mortar: warning: {message}")
    import warnings
    warnings.showwarning = show_warning
    out = args.out or Path("results") / args.scene.stem
    check_petsc_options(scene.solver)      # before --out is made for a scene refused
    _check_jit_cache(comm)
    with _locked(out, comm, "--restart" if args.restart is not None else "--out"):
        result = solve(scene, out, comm, restart=args.restart is not None)
    if comm.rank == 0:
        t = result.timings
        print(f"summary: {'converged' if result.converged else 'NOT converged'}, "
              f"{len(result.steps)} steps, "
              f"{sum(s['newton_iterations'] for s in result.steps)} Newton iterations, "
              f"{t.get('total', 0):.2f} s total; outputs in {out}")
        if result.steps:
            for name, c in result.steps[-1].get("contact", {}).items():
                print(f"contact {name}: normal force {c['normal_force']:.6g}, max pressure "
                      f"{c['max_pressure']:.6g}, {c['active_nodes']} active nodes, "
                      f"KKT residual {c['kkt_residual']:.1e}")
        if not result.converged:
            # the why, in one line where scripts look for it (the log has the residuals)
            why = re.sub(r", residuals [^;]*", "", result.message.splitlines()[0])
            _say(f"fenicsx-mortar: error: run failed: {why}")
    return 0 if result.converged else 1


@contextlib.contextmanager
def _locked(out: Path, comm, key: str):
    """``out`` made (``--out``) and locked by rank 0 for the run: a second run into it is
    refused by name on every rank."""
    from .io.output import locked, prepare_out
    from .scene.parallel import on_rank0
    with contextlib.ExitStack() as stack:
        def take() -> None:
            if key == "--out":
                prepare_out(out)
            stack.enter_context(locked(out, key))
        on_rank0(comm, take)
        yield


def _check_jit_cache(comm) -> None:
    """The JIT (FFCx's compiled forms) must find its settings and a cache directory this
    process can write (every rank): else the compile fails deep inside DOLFINx with a
    traceback. No settings file in the working directory: it would set compiler flags
    (code run by the compiler) or put the cache anywhere. Raises RunError naming the place
    and the variable that sets it."""
    from . import _dolfinx as dx
    from .scene.parallel import RunError, agree

    def probe() -> None:
        import tempfile
        here = [n for n in JIT_SETTINGS_FILES if Path(n).exists()]
        if here:
            raise RunError(f"{Path.cwd() / here[0]}: DOLFINx and FFCx read their JIT settings "
                           "(compiler flags, the cache's place, the number type) from a file "
                           "of this name in the working directory; the command line does not "
                           "run with one: remove it or run elsewhere (settings in "
                           "XDG_CONFIG_HOME are yours and are kept)")
        try:
            cache = Path(dx.jit_cache_dir())
        except OSError as e:     # its settings file (~/.config/dolfinx/...) is unreadable
            raise RunError(f"DOLFINx cannot read its JIT settings {e.filename} "
                           f"({e.strerror}): the place is set by "
                           f"{_placed_by('XDG_CONFIG_HOME')}; set XDG_CONFIG_HOME to a "
                           "readable directory") from None
        try:
            cache.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryFile(dir=cache):
                pass
        except OSError as e:
            raise RunError(f"the JIT cache {cache} is not a writable directory "
                           f"({e.strerror}): the place is set by "
                           f"{_placed_by('XDG_CACHE_HOME')}; set XDG_CACHE_HOME to a "
                           "writable directory") from None
    agree(comm, probe)


def _jit_failure(e: Exception) -> str | None:
    """The one-line message of a JIT failure that a broken cache entry explains (a
    truncated or foreign module: ImportError; a C file without its module, left by a
    compile that was killed: FFCx's TimeoutError; under MPI DOLFINx's RuntimeError for
    either), or None for any other error."""
    text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    if isinstance(e, TimeoutError) or (isinstance(e, ImportError) and (
            "JIT module" in text or "libffcx_" in text)) or (
            isinstance(e, RuntimeError) and text.startswith("Failed just-in-time")):
        from . import _dolfinx as dx
        try:
            cache = dx.jit_cache_dir()
        except OSError:
            cache = "of DOLFINx"
        return (f"the JIT cache {cache} has a broken entry ({type(e).__name__}: {text}); "
                "remove the directory (it is made again) and run again")
    return None


def _placed_by(variable: str) -> str:
    return variable if os.environ.get(variable) else f"HOME ({variable} is not set)"


def _abort_all(comm, e: Exception) -> None:
    """One line, then MPI_Abort: rank 0 says it; another rank gives rank 0 0.8 s to (rank 0
    may be deep in gmsh, or in a collective HDF5 call, where no signal handler runs) and
    then says it itself. Rank 0 gives mpirun's output forwarding a moment before
    it aborts (an abort right after the write lost the line in 1 of 3 runs). mpirun ends
    the ranks still waiting with SIGTERM: they die of it, without a traceback."""
    import time
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_DFL)
    if comm.rank != 0:
        time.sleep(0.8)          # mpirun's SIGKILL follows its SIGTERM after 1 s
    _say(f"fenicsx-mortar: error: {e}")
    time.sleep(0.3)
    comm.Abort(1)


def _say(line: str) -> None:
    # one write: stderr is write-through, and print() writes the text and its newline
    # separately; under Open MPI 5 a run once showed the newline alone on stderr
    # (tests/hostile mpi_disk_full)
    sys.stderr.write(line + "\n")
    sys.stderr.flush()


def _error(comm, e: Exception) -> None:
    if comm.rank == 0:
        text = " ".join(str(e).split("\n"))
        _say(f"fenicsx-mortar: error: {text}")


class _Interrupt:
    """SIGINT and SIGTERM outside the load steps (start-up: reading, meshing, compiling;
    or the final writes) end the run with one line and exit 1 instead of a traceback or a
    bare kill. The exception is an ``Exception``, not a ``KeyboardInterrupt``, so FFCx
    clears its half-compiled module from the JIT cache on the way out. During the load
    steps run.py's own handler stops at the next Newton iteration."""

    def __enter__(self):
        self._old = {}
        if threading.current_thread() is threading.main_thread():
            # gmsh 4.8 sets SIGINT to the default action when imported and gmsh.finalize()
            # puts back the handler it found then: import it first, and make that ours
            import gmsh
            self._gmsh = getattr(gmsh, "oldsig", None)
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._raise)
            gmsh.oldsig = self._raise
        return self

    def __exit__(self, *exc):
        if self._old:
            import gmsh
            gmsh.oldsig = self._gmsh
        for sig, old in self._old.items():
            signal.signal(sig, old)

    @staticmethod
    def _raise(signum, frame):
        from .scene.parallel import Interrupted
        run = sys.modules.get("fenicsx_mortar.scene.runner")   # not imported yet: still reading
        doing = run.phase() if run else "reading the scene"
        raise Interrupted(f"interrupted by {signal.Signals(signum).name} while {doing}; "
                       "what converged is kept")


def _study(argv: list[str]) -> int:
    """The study lives in the repository (benchmarks/study), not in the package: found next
    to the package's directory, i.e. in a source checkout (editable install)."""
    root = Path(__file__).resolve().parents[1]
    if not (root / "benchmarks" / "study" / "__main__.py").is_file():
        print("fenicsx-mortar: the study runs from a source checkout: "
              "python -m benchmarks.study [--quick] [--out DIR] (in the repository root)",
              file=sys.stderr)
        return 2
    sys.path.insert(0, str(root))
    from benchmarks.study.__main__ import main as study
    return study(argv, prog="fenicsx-mortar study")


if __name__ == "__main__":
    sys.exit(main())

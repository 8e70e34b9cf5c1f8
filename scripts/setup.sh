#!/usr/bin/env bash
# Idempotent set-up of .venv, by one of two routes (DOLFINX=apt|pip, make ... DOLFINX=pip):
#
#   apt  Debian 12 (DOLFINx 0.5.2) or 13 (0.9.0): Debian's DOLFINx stack, then a venv that
#        sees it (--system-site-packages: Debian's DOLFINx is importable only by
#        /usr/bin/python3) with fenicsx_mortar installed editable and ruff (the lint step).
#   pip  any Linux with a Python >= 3.12: a plain venv of that Python with DOLFINx 0.11
#        (PyPI's dolfinx-solver-real, on the mpich wheel's MPICH), gmsh and the rest from
#        PyPI through the 'dolfinx' extra of pyproject.toml; on Debian also the few apt
#        libraries gmsh's wheel and the FFCx JIT need.
#
# Without DOLFINX: the route of an existing .venv, else apt on Debian 12/13, else pip where
# a Python >= 3.12 is found (PYTHON=/path/to/python picks one). A .venv of the other route or
# of another Python is made again. Fast when already done.
set -euo pipefail
cd "$(dirname "$0")/.."

# The Debian release by /etc/debian_version ("12.11", "13.2"; testing: "trixie/sid").
debian_release() {
  local v
  v=$(cat /etc/debian_version 2>/dev/null) || { echo none; return; }
  case "$v" in
    12|12.*|bookworm*) echo 12 ;;
    13|13.*|trixie*) echo 13 ;;
    *) echo "other:$v" ;;
  esac
}

sudo=""; [ "$(id -u)" -ne 0 ] && sudo=sudo
apt_install() {
  local p missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "setup: installing ${missing[*]} (Debian $release)"
    $sudo apt-get update -q
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q "${missing[@]}"
  fi
}

# The first Python >= 3.12 that can make a venv: $PYTHON, the system's, PATH's, pyenv's.
find_python() {
  local c
  for c in ${PYTHON:-} /usr/bin/python3 python3 python3.14 python3.13 python3.12 \
           /usr/local/bin/python3 "${PYENV_ROOT:-$HOME/.pyenv}"/versions/*/bin/python3; do
    if "$c" -c 'import sys; sys.exit(sys.version_info < (3, 12))' 2>/dev/null; then
      "$c" -c 'import sys; print(sys.executable)'
      return 0
    fi
  done
  return 1
}

release=$(debian_release)
route=${DOLFINX:-}
stamp_route=.venv/.fenicsx_mortar-route
case "$route" in
  apt|pip) ;;
  "")
    if [ -f "$stamp_route" ]; then route=$(cat "$stamp_route")
    elif [ -x .venv/bin/python ]; then route=apt          # made before the pip route existed
    elif [ "$release" = 12 ] || [ "$release" = 13 ]; then route=apt
    elif find_python >/dev/null; then route=pip
    else route=none
    fi ;;
  *) echo "setup: DOLFINX=$route: give apt (Debian's DOLFINx) or pip (DOLFINx 0.11 from PyPI)" >&2
     exit 2 ;;
esac

if [ "$route" = none ] || { [ "$route" = apt ] && [ "$release" != 12 ] && [ "$release" != 13 ]; }; then
  what=$( (. /etc/os-release 2>/dev/null && echo "$PRETTY_NAME") || true)
  [ -n "$what" ] || what="this system"
  [ "${release#other:}" != "$release" ] && what="$what (/etc/debian_version: ${release#other:})"
  echo "setup: Debian's DOLFINx (DOLFINX=apt) is for Debian 12 or 13, not $what, and no" \
       "Python >= 3.12 was found for DOLFINx 0.11 from PyPI (DOLFINX=pip)." >&2
  echo "setup: install Python 3.12 or newer (with venv and its C headers) and a C compiler," \
       "then run 'make test DOLFINX=pip' (or PYTHON=/path/to/python3.12 bash" \
       "scripts/setup.sh); or install DOLFINx 0.5, 0.9, 0.10 or 0.11 yourself and" \
       "'pip install -e . ruff' into a venv whose Python imports it." >&2
  exit 1
fi

# A venv of the other route, or made by another Python (the machine was upgraded from 12 to
# 13, the directory was copied), cannot import its DOLFINx: empty it and make it again
# (emptied, not removed: in scripts/debian_root.sh's root .venv is a mount point).
pyver() { "$1" -c 'import sys; print(*sys.version_info[:2])' 2>/dev/null; }
remake() {
  echo "setup: $1: making .venv again"
  find .venv -mindepth 1 -maxdepth 1 -exec rm -rf {} +
}
old_route=""
if [ -e .venv/pyvenv.cfg ]; then
  old_route=apt; [ -f "$stamp_route" ] && old_route=$(cat "$stamp_route")
fi

if [ "$route" = apt ]; then
  # The same package names on both releases: DOLFINx 0.5.2 on 12, 0.9.0 on 13. OpenBLAS
  # (serial: MPI is the parallelism): DOLFINx pulls in only the reference BLAS, on which
  # MUMPS's factorizations take 1.5x as long (docs/performance.md); installed, Debian makes
  # it the system BLAS unless an administrator pinned another one.
  apt_install python3-dolfinx-real python3-gmsh python3-pytest python3-matplotlib \
    python3-scipy python3-pil python3-venv python3-setuptools python3-wheel openmpi-bin \
    libopenblas0-serial
  blas=$(update-alternatives --query libblas.so.3-x86_64-linux-gnu 2>/dev/null |
         sed -n 's/^Status: //p; s/^Value: //p' | tr '\n' ' ' || true)
  case "$blas" in
    "manual "*/blas/libblas.so.3*)
      echo "setup: note: the system BLAS is the reference one (pinned with update-alternatives);" \
           "'update-alternatives --auto libblas.so.3-x86_64-linux-gnu' (and liblapack.so.3-...)" \
           "selects OpenBLAS, with which the linear solves are 1.5x faster" ;;
  esac
  python=/usr/bin/python3
  if [ -n "$old_route" ] && [ "$old_route" != apt ]; then remake "it was made for DOLFINX=$old_route"
  elif [ -e .venv/pyvenv.cfg ] && [ "$(pyver .venv/bin/python)" != "$(pyver $python)" ]; then
    remake "it was made by another Python than $python"
  fi
  if [ ! -x .venv/bin/python ]; then
    $python -m venv --system-site-packages .venv
  fi
else
  if [ "$release" = 12 ] || [ "$release" = 13 ]; then
    # gmsh's wheel links X11/OpenGL libraries; the FFCx JIT compiles C against Python.h
    apt_install libglu1-mesa libgl1 libxcursor1 libxft2 libxinerama1 gcc python3-venv \
      python3-dev
  fi
  python=$(find_python) || {
    echo "setup: DOLFINX=pip needs Python >= 3.12 (DOLFINx 0.11's wheel); none found" \
         "(/usr/bin/python3 is $(pyver /usr/bin/python3 | tr ' ' .)); set PYTHON=/path/to/python3.12" >&2
    exit 1; }
  if ! "$python" -c 'import sysconfig, os, sys
sys.exit(not os.path.exists(os.path.join(sysconfig.get_paths()["include"], "Python.h")))'; then
    echo "setup: $python has no C headers (Python.h), which DOLFINx's JIT compiles against;" \
         "install its development package" >&2
    exit 1
  fi
  if [ -n "$old_route" ] && [ "$old_route" != pip ]; then remake "it was made for DOLFINX=$old_route"
  elif [ -e .venv/pyvenv.cfg ] && [ "$(pyver .venv/bin/python)" != "$(pyver "$python")" ]; then
    remake "it was made by another Python than $python"
  fi
  if [ ! -x .venv/bin/python ]; then
    echo "setup: DOLFINx 0.11 from PyPI into .venv ($python, Python $(pyver "$python" | tr ' ' .))"
    "$python" -m venv .venv
  fi
fi
echo "$route" >"$stamp_route"

# The lint step's tool (CI runs `ruff check .`), from PyPI into the venv.
if [ ! -x .venv/bin/ruff ]; then
  .venv/bin/python -m pip install -q ruff
fi
# Re-install only when the project metadata changed (editable install: code changes need nothing).
stamp=.venv/.fenicsx_mortar-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  if [ "$route" = apt ]; then
    .venv/bin/python -m pip install -q --no-build-isolation --no-deps -e .
  else
    .venv/bin/python -m pip install -q -e ".[dolfinx,test]"
  fi
  touch "$stamp"
fi
# Test dependencies Debian does not package: hypothesis (the scene loader's property test).
if ! .venv/bin/python -c "import hypothesis" 2>/dev/null; then
  .venv/bin/python -m pip install -q "hypothesis>=6"
fi
if [ "$route" = pip ] && ! .venv/bin/python -c "import gmsh" 2>/dev/null; then
  echo "setup: gmsh's wheel does not load: $(.venv/bin/python -c 'import gmsh' 2>&1 | tail -1)" \
       "(it needs the system's libGLU, libGL, libXcursor, libXft and libXinerama)" >&2
  exit 1
fi

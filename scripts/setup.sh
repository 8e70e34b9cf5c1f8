#!/usr/bin/env bash
# Idempotent set-up on Debian 12 (DOLFINx 0.5.2) or Debian 13 (DOLFINx 0.9.0): Debian's
# DOLFINx stack, then a venv that sees it (--system-site-packages: DOLFINx is importable only
# by Debian's /usr/bin/python3) with fenicsx_mortar installed editable and ruff (the lint
# step). Fast when already done. Other systems are refused with what to install instead.
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

release=$(debian_release)
case "$release" in
  12|13) ;;
  *)
    what=$( (. /etc/os-release 2>/dev/null && echo "$PRETTY_NAME") || true)
    [ -n "$what" ] || what="this system"
    [ "${release#other:}" != "$release" ] && what="$what (/etc/debian_version: ${release#other:})"
    echo "setup: scripts/setup.sh installs the stack on Debian 12 or 13 only, not on $what." >&2
    echo "setup: install DOLFINx 0.5 or 0.9 for Python 3 (with petsc4py, mpi4py, UFL, basix," \
         "FFCx), gmsh's Python module, SciPy, Matplotlib, Pillow, pytest and Open MPI, then" \
         "make .venv with a Python that imports dolfinx and run" \
         "'.venv/bin/pip install -e . ruff' in it." >&2
    exit 1 ;;
esac

# The same package names on both releases: DOLFINx 0.5.2 on 12, 0.9.0 on 13. OpenBLAS
# (serial: MPI is the parallelism): DOLFINx pulls in only the reference BLAS, on which
# MUMPS's factorizations take 1.5x as long (docs/performance.md); installed, Debian makes it
# the system BLAS unless an administrator pinned another one.
pkgs=(python3-dolfinx-real python3-gmsh python3-pytest python3-matplotlib python3-scipy
      python3-pil python3-venv python3-setuptools python3-wheel openmpi-bin libopenblas0-serial)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""; [ "$(id -u)" -ne 0 ] && sudo=sudo
  echo "setup: installing ${missing[*]} (Debian $release)"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q "${missing[@]}"
fi

blas=$(update-alternatives --query libblas.so.3-x86_64-linux-gnu 2>/dev/null |
       sed -n 's/^Status: //p; s/^Value: //p' | tr '\n' ' ' || true)
case "$blas" in
  "manual "*/blas/libblas.so.3*)
    echo "setup: note: the system BLAS is the reference one (pinned with update-alternatives);" \
         "'update-alternatives --auto libblas.so.3-x86_64-linux-gnu' (and liblapack.so.3-...)" \
         "selects OpenBLAS, with which the linear solves are 1.5x faster" ;;
esac

# A venv made by another Python (the machine was upgraded from 12 to 13, or the directory
# was copied) cannot import the system's DOLFINx: empty it and make it again (emptied, not
# removed: in scripts/debian_root.sh's root .venv is a mount point).
pyver() { "$1" -c 'import sys; print(*sys.version_info[:2])' 2>/dev/null; }
if [ -e .venv/pyvenv.cfg ] && [ "$(pyver .venv/bin/python)" != "$(pyver /usr/bin/python3)" ]; then
  echo "setup: .venv was made by another Python than /usr/bin/python3: making it again"
  find .venv -mindepth 1 -maxdepth 1 -exec rm -rf {} +
fi
if [ ! -x .venv/bin/python ]; then
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
# The lint step's tool (CI runs `ruff check .`), from PyPI into the venv.
if [ ! -x .venv/bin/ruff ]; then
  .venv/bin/python -m pip install -q ruff
fi
# Re-install only when the project metadata changed (editable install: code changes need nothing).
stamp=.venv/.fenicsx_mortar-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  .venv/bin/python -m pip install -q --no-build-isolation --no-deps -e .
  touch "$stamp"
fi
# Test dependencies Debian does not package: hypothesis (the scene loader's property test).
if ! .venv/bin/python -c "import hypothesis" 2>/dev/null; then
  .venv/bin/python -m pip install -q "hypothesis>=6"
fi

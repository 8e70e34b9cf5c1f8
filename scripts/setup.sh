#!/usr/bin/env bash
# Idempotent set-up on Debian 12: Debian's DOLFINx 0.5.2 stack, then a venv that sees it
# (--system-site-packages) with fenicsx_mortar installed editable. Fast when already done.
set -euo pipefail
cd "$(dirname "$0")/.."

pkgs=(python3-dolfinx-real python3-gmsh python3-pytest python3-matplotlib python3-scipy
      python3-pil python3-venv python3-setuptools python3-wheel openmpi-bin)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""; [ "$(id -u)" -ne 0 ] && sudo=sudo
  echo "setup: installing ${missing[*]}"
  $sudo apt-get update -q
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -q "${missing[@]}"
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

# Both targets install what they need first (apt packages, .venv) and are fast once done.
# DOLFINX=apt: Debian's DOLFINx (0.5.2 on Debian 12, 0.9 on 13); DOLFINX=pip: DOLFINx 0.11
# from PyPI into .venv with a Python >= 3.12; unset: see scripts/setup.sh.
.PHONY: setup demo test
SCENE ?= demos/scenes/patch_test.toml
DOLFINX ?=

setup:
	@DOLFINX=$(DOLFINX) bash scripts/setup.sh

demo: setup
	.venv/bin/fenicsx-mortar run $(SCENE) --out results/$(basename $(notdir $(SCENE)))

test: setup
	.venv/bin/python -m pytest -q

# Both targets install what they need first (apt packages, .venv) and are fast once done.
.PHONY: setup demo test
SCENE ?= demos/scenes/patch_test.toml

setup:
	@bash scripts/setup.sh

demo: setup
	.venv/bin/fenicsx-mortar run $(SCENE) --out results/$(basename $(notdir $(SCENE)))

test: setup
	.venv/bin/python -m pytest -q

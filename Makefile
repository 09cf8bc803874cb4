# navbench: `make run` (set up + main job on bundled data) and `make test` (set up + tests).
# Works as root on a fresh Debian 12 machine: creates .venv, installs the OSMesa libraries only when
# missing, then installs navbench with its dev and models extras (tiny random models test the real
# perception backends; no weights are downloaded).
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup osmesa run test test-slow bench clean results-oracle results-localize

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip

# OSMesa (headless software OpenGL) for pyrender; apt runs only when the library is missing.
osmesa:
	@if ! ldconfig -p | grep -q libOSMesa.so; then \
	  echo "installing libosmesa6 (apt)"; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libosmesa6 libosmesa6-dev >/dev/null; \
	fi

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/pip install -q -e ".[dev,models]"
	touch $(STAMP)

setup: osmesa $(STAMP)

run: setup
	$(BIN)/navbench run --split val_unseen

test: setup
	$(BIN)/python -m pytest

test-slow: setup
	$(BIN)/python -m pytest -m slow

bench: setup
	$(BIN)/navbench bench

clean:
	rm -rf $(VENV) .pytest_cache

# Reference tables in results/ (each command is also printed in results/README.md).
ORACLE_SPLITS := val_seen val_seen_synonyms val_unseen
results-oracle: setup
	for s in $(ORACLE_SPLITS); do $(BIN)/navbench run --split $$s --agent oracle --out results/runs/oracle_$$s -q || exit 1; done
	$(BIN)/navbench run --task pointnav --split val --agent oracle --out results/runs/oracle_pointnav_val -q
	$(BIN)/navbench table $(addprefix results/runs/oracle_,$(ORACLE_SPLITS)) > results/oracle_objectnav.md
	$(BIN)/navbench table results/runs/oracle_pointnav_val --long > results/oracle_pointnav.md

# Localisation SR@5 (GOAT-style goat_val): oracle perception, with/without noise and fusion.
results-localize: setup
	$(BIN)/navbench localize --split goat_val --perception oracle --noise none --out results/localize/oracle_none_fusion
	$(BIN)/navbench localize --split goat_val --perception oracle --noise none --no-fusion --out results/localize/oracle_none_single
	$(BIN)/navbench localize --split goat_val --perception oracle --noise default --out results/localize/oracle_default_fusion
	$(BIN)/navbench localize --split goat_val --perception oracle --noise default --no-fusion --out results/localize/oracle_default_single
	$(BIN)/navbench localize --split goat_val --perception oracle --noise heavy --out results/localize/oracle_heavy_fusion
	$(BIN)/navbench localize --split goat_val --perception oracle --noise heavy --no-fusion --out results/localize/oracle_heavy_single
	$(BIN)/python -m navbench.localize.report results/localize > results/localization_sr5.md

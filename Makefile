# navbench: `make run` (set up + the main job on the bundled data) and `make test` (set up + the tests).
# As root on a fresh Debian 12 machine: .venv, OSMesa only when missing, navbench with its extras.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
NB := $(BIN)/navbench
RUNS := results/runs
RUN := $(NB) run --runs-dir $(RUNS) --overwrite -q
OBJNAV_SPLITS := val_seen val_seen_synonyms val_unseen
LIMIT_ARG = $(if $(LIMIT),--limit $(LIMIT),)
BENCH ?= runs/benchmark_h36
.PHONY: setup osmesa run test test-slow bench clean results-oracle results-localize results-pointnav results-pointnav-2h \
	results-objectnav results-objectnav-least-tried tables-objectnav results-memory train-pointnav train-pointnav-2h \
	figures wheel-check lint results-benchmark results-realistic results-vlnce results-tasks test-habitat
$(BIN)/python: ; $(PY) -m venv $(VENV) && $(BIN)/pip install -q --upgrade pip
osmesa:  # OSMesa (headless software OpenGL) for pyrender; apt runs only when the library is missing
	@ldconfig -p | grep -q libOSMesa.so || { echo "installing libosmesa6 (apt)"; apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libosmesa6 libosmesa6-dev >/dev/null; }
$(STAMP): pyproject.toml constraints/ci.txt | $(BIN)/python  # ci.txt: the torch build tested (pyproject: the range)
	$(BIN)/pip install -q -c constraints/ci.txt -e ".[dev,models,viz,ray]"
	touch $(STAMP)
setup: osmesa $(STAMP)
run: setup ; $(NB) run --split val_unseen  # the memory agent on ObjectNav val_unseen: the README's headline figures
test: setup ; $(BIN)/python -m pytest
test-slow: setup  # slow end-to-end checks (reference runs reproduce); first triton and SB3, as a CUDA torch from pip brings
	$(BIN)/pip install -q -c constraints/ci.txt triton==3.8.0 "stable-baselines3>=2.9" && $(BIN)/python -m pytest -m slow
# habitat-lab and habitat-baselines on navbench (docs/habitat_lab.md), in their own virtualenv made by the README's line
.hvenv/.installed: pyproject.toml compat/habitat-sim/pyproject.toml
	$(PY) -m venv .hvenv && .hvenv/bin/pip install -q -e ".[habitat]" -e compat/habitat-sim "pytest>=8" "hypothesis>=6.100" && touch $@
test-habitat: osmesa .hvenv/.installed  # and navbench's scene, render, env and episode tests on habitat-lab's numpy 1.26.4
	NAVBENCH_REQUIRE_HABITAT=1 .hvenv/bin/python -m pytest tests/habitat_sim tests/scene tests/render tests/env tests/episodes
wheel-check: setup ; bash tests/wheel_check.sh $(BIN)/python $(PY)  # sdist + wheel, then the wheel alone in a fresh venv
bench: setup ; $(NB) bench
lint: setup  # ruff, pyright on the public modules (pyproject.toml), the import order of docs/layout.md
	$(BIN)/ruff check . && $(BIN)/pyright && $(BIN)/python -m pytest -q tests/test_layout.py
clean: ; rm -rf $(VENV) .hvenv .pytest_cache dist build
# Reference tables in results/ (results/README.md); runs land in results/runs/<task>/<split>/<label>/; LIMIT=N: first N each.
results-oracle: setup
	for s in $(OBJNAV_SPLITS); do $(RUN) --split $$s --agent oracle $(LIMIT_ARG) || exit 1; done
	$(NB) table $(RUNS)/objectnav/*/oracle > results/oracle_objectnav.md
	for t in pointnav imagenav; do $(RUN) --task $$t --split val --agent oracle $(LIMIT_ARG) && \
	  $(NB) table --long $(RUNS)/$$t/val/oracle > results/oracle_$$t.md || exit 1; done
results-localize: setup
	for n in none default heavy; do \
	  $(NB) localize --split goat_val --noise $$n --out results/localize/oracle_$${n}_fusion || exit 1; \
	  $(NB) localize --split goat_val --noise $$n --no-fusion --out results/localize/oracle_$${n}_single || exit 1; \
	done
	$(BIN)/python -m navbench.localize.report results/localize > results/localization_sr5.md
results-pointnav: setup  # the default file, then policies/pointnav_v2.pth
	$(RUN) --task pointnav --split val --agent optimistic $(LIMIT_ARG)
	for c in "" "--checkpoint policies/pointnav_v2.pth"; do for o in "val" "select" "val --decoding argmax"; do \
	  $(RUN) --task pointnav --split $$o $$c $(LIMIT_ARG) || exit 1; done; done
	$(NB) table --long $(addprefix $(RUNS)/pointnav/val/,oracle optimistic pointnav pointnav-argmax pointnav-pointnav_v2 \
	  pointnav-pointnav_v2-argmax) \
	  $(RUNS)/pointnav/select/pointnav $(RUNS)/pointnav/select/pointnav-pointnav_v2 > results/pointnav.md
results-pointnav-2h: setup
	$(RUN) --task pointnav --split val --checkpoint policies/pointnav_2h.pth --decoding argmax $(LIMIT_ARG)
	for s in 0 1 2 3 4; do $(RUN) --task pointnav --split val --checkpoint policies/pointnav_2h.pth --seed $$s $(LIMIT_ARG) || exit 1; done
	$(RUN) --task pointnav --split select --checkpoint policies/pointnav_2h.pth $(LIMIT_ARG)
	$(NB) table --long $(RUNS)/pointnav/*/pointnav-pointnav_2h* > results/pointnav_2h.md
results-objectnav: setup
	for s in $(OBJNAV_SPLITS); do \
	  for a in "memory" "memory --rerank none" "frontier"; do $(RUN) --split $$s --agent $$a $(LIMIT_ARG) || exit 1; done; \
	done
	for o in "--noise default" "--checkpoint policies/pointnav_v2.pth"; do \
	  $(RUN) --split val_unseen --agent memory $$o $(LIMIT_ARG) || exit 1; done
	$(MAKE) tables-objectnav
tables-objectnav: setup
	{ echo "## All agents, SR / SPL (%)"; echo; \
	  $(NB) table $(foreach a,frontier memory-norerank memory oracle,$(foreach s,$(OBJNAV_SPLITS),$(RUNS)/objectnav/$(s)/$(a))); \
	  echo; echo "## Memory agent and oracle, with SoftSPL and distance to goal"; echo; \
	  $(NB) table --long $(foreach a,memory oracle,$(foreach s,$(OBJNAV_SPLITS),$(RUNS)/objectnav/$(s)/$(a))) \
	    $(RUNS)/objectnav/val_unseen/memory-noise_default $(RUNS)/objectnav/val_unseen/memory-pointnav_v2; } > results/objectnav.md
	$(BIN)/python -m navbench.eval.failures $(foreach a,frontier memory-norerank memory,$(foreach s,$(OBJNAV_SPLITS),\
	  $(RUNS)/objectnav/$(s)/$(a))) $(RUNS)/objectnav/val_unseen/memory-noise_default > results/objectnav_failures.md
results-objectnav-least-tried: setup
	for s in $(OBJNAV_SPLITS); do for a in memory frontier; do \
	  $(RUN) --split $$s --agent $$a --decoding least-tried $(LIMIT_ARG) || exit 1; done; done
	$(NB) table $(foreach a,frontier memory,$(foreach s,$(OBJNAV_SPLITS),$(RUNS)/objectnav/$(s)/$(a)-least-tried)) \
	  > results/objectnav_least_tried.md
results-memory: setup
	test -f $(RUNS)/objectnav/val_unseen/memory/summary.json || $(RUN) --split val_unseen --agent memory
	for v in "--all-frames" "--keyframe-res 640x480" "--keyframe-res 160x120"; do \
	  $(RUN) --split val_unseen --agent memory $$v --limit 20 || exit 1; done
	$(BIN)/python -m navbench.eval.memory_table --first 20 $(foreach v,memory memory-allframes memory-640x480 \
	  memory-160x120,$(RUNS)/objectnav/val_unseen/$(v)) > results/memory_efficiency.md
results-benchmark: setup  # the generated 36-house benchmark's val_unseen (docs/comparing.md); BENCH holds its files
	test -f $(BENCH)/SHA256SUMS || $(NB) generate benchmark --houses 36 --episodes-per-split 3000 --out $(BENCH)
	for a in memory frontier; do $(RUN) --agent $$a --episodes $(BENCH)/objectnav/val_unseen_h36.json.gz \
	  --scene-dir $(BENCH)/scenes $(LIMIT_ARG) || exit 1; done
	h=$(RUNS)/objectnav/val_unseen_h36; { echo '# Generated benchmark (36 houses), val_unseen: `make results-benchmark`'; \
	  echo; $(NB) table $$h/*; echo; echo '```'; $(NB) compare $$h/frontier $$h/memory; echo '```'; } > results/benchmark_h36.md
results-realistic: setup ; NB="$(NB)" RUNS=$(RUNS) bash results/realistic.sh all  # docs/realistic.md; resumable
results-vlnce: setup ; NB="$(NB)" RUNS=$(RUNS) bash results/vlnce.sh > results/vlnce.md  # R2R-CE baselines, ~20 min
results-tasks: setup ; NB="$(NB)" PY=$(BIN)/python RUNS=$(RUNS) bash results/tasks.sh all  # InstanceImageNav, GOAT, ImageNav
figures: setup ; NB=$(NB) bash docs/figures.sh  # docs/img/topdown.png and docs/img/report.png, the README's pictures
# The shipped PointNav checkpoints' recipes (policies/MODEL_CARD.md); outputs under runs/pointnav/.
train-pointnav: setup ; $(NB) train --config configs/pointnav/full.toml
train-pointnav-2h: setup ; $(NB) train --config configs/pointnav/2h.toml

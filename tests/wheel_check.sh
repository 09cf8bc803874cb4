#!/usr/bin/env bash
# make wheel-check: build the sdist and the wheel (dist/), install the wheel into a fresh venv (torch as the
# Makefile installs it: the tested build pinned by constraints/ci.txt), then from an empty directory outside the checkout run both
# tasks on 2 episodes, compare their records with the committed reference runs, and load the bundled recipes.
#     tests/wheel_check.sh PYTHON_WITH_BUILD [BASE_PYTHON]
set -euo pipefail
cd "$(dirname "$0")/.."
checkout=$PWD
build_py=$1
base_py=${2:-python3}
rm -rf dist
"$build_py" -m build --outdir dist . >/dev/null
ls -l dist
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$base_py" -m venv "$work/venv"
"$work/venv/bin/pip" install -q -c "$checkout/constraints/ci.txt" dist/navbench-*.whl
mkdir "$work/empty"
cd "$work/empty"
export NAVBENCH_CACHE="$work/cache"
unset PYTHONPATH NAVBENCH_DATA
nb="$work/venv/bin/navbench"
"$nb" --version
python="$work/venv/bin/python"
"$python" -c "import navbench.paths as p; assert '/site-packages/' in str(p.ROOT), p.ROOT; print('data:', p.ROOT)"
"$nb" run --limit 2 -q
"$nb" run --task pointnav --limit 2 -q
"$python" - "$checkout/results/runs" <<'PY'
import json, sys
from pathlib import Path
from navbench.policy.recipe import load_recipe
keys = ("success", "spl", "soft_spl", "distance_to_goal", "num_steps", "path_length")
for run in ("objectnav/val_unseen/memory", "pointnav/val/pointnav"):
    ref = {r["episode_id"]: r for r in map(json.loads, open(Path(sys.argv[1]) / run / "episodes.jsonl"))}
    got = [json.loads(line) for line in open(Path("runs") / run / "episodes.jsonl")]
    assert len(got) == 2 and all(r[k] == ref[r["episode_id"]][k] for r in got for k in keys), run
    print(f"{run}: the wheel's records equal the reference run's")
for name in ("2h", "full"):
    print(f"recipe {name}: stages", ", ".join(s.name for s in load_recipe(name).stages))
PY
echo "wheel check passed"

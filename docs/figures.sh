#!/usr/bin/env bash
# The README's pictures: a top-down map of a frontier episode that explores much of its house, and a screenshot
# of a run report.
# Needs the viz extra (make setup installs it) and Debian's chromium for the screenshot.
#     bash docs/figures.sh   (or: make figures)
set -euo pipefail
cd "$(dirname "$0")/.."
NB=${NB:-.venv/bin/navbench}
FIG=runs/figures
for agent in frontier memory; do
  "$NB" run --split val_unseen --agent "$agent" --limit 12 --runs-dir "$FIG" --overwrite -q --video failures
done
"$NB" viz "$FIG/objectnav/val_unseen/frontier" --episode 11 --size 560 -o "$FIG/maps"
cp "$FIG/maps/11.png" docs/img/topdown.png
"$NB" report "$FIG/objectnav/val_unseen/memory" "$FIG/objectnav/val_unseen/frontier" -o "$FIG/report.html"
command -v chromium >/dev/null || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; }
chromium --headless=new --no-sandbox --disable-gpu --hide-scrollbars --window-size=1200,1500 \
  --screenshot=docs/img/report.png "file://$PWD/$FIG/report.html"

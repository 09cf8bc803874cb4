#!/usr/bin/env bash
# results/realistic.md from the runs `make results-realistic` makes (NB, RUNS, K, KC, CONDITIONS from the Makefile).
# A run that is not there yet is listed as missing, so the page can be written while runs go on.
set -u
echo "# Realistic conditions: actuation and sensor noise (\`make results-realistic\`)"
echo
echo "Each agent under each condition of \`configs/env/\` (docs/realistic.md), on the first $K episodes of each"
echo "scene, against its noiseless reference run on the same episodes (\`navbench compare --per-scene $K\`:"
echo "paired intervals, noisy minus noiseless). The protocols differ (that is the point), hence \`--mix-protocols\`."
echo "The Habitat Challenge 2021 PointNav run uses the first $KC episodes of each scene."
section() {  # section TITLE BASE_RUN PER_SCENE RUN...
  local title=$1 base=$2 k=$3; shift 3
  echo; echo "## $title"; echo
  local have=()
  for r in "$@"; do
    if [ -f "$r/summary.json" ]; then have+=("$r"); else echo "- missing: \`$r\` (run \`make results-realistic\`)"; fi
  done
  [ ${#have[@]} -eq 0 ] && return
  echo "\`navbench table --mix-protocols ${have[*]}\`"; echo
  $NB table --mix-protocols "${have[@]}"
  for r in "${have[@]}"; do
    echo; echo "\`navbench compare --mix-protocols --per-scene $k $base $r\`"; echo; echo '```'
    $NB compare --mix-protocols --per-scene "$k" "$base" "$r"; echo '```'
  done
}
runs() { for c in $CONDITIONS; do echo "$RUNS/$1-$c"; done; }
section "Memory agent, ObjectNav val_unseen" "$RUNS/objectnav/val_unseen/memory" "$K" $(runs objectnav/val_unseen/memory)
section "Frontier agent, ObjectNav val_unseen" "$RUNS/objectnav/val_unseen/frontier" "$K" \
  $(runs objectnav/val_unseen/frontier)
section "PointNav policy, PointNav val" "$RUNS/pointnav/val/pointnav" "$K" $(runs pointnav/val/pointnav)
section "PointNav policy, Habitat Challenge 2021 PointNav configuration (no GPS+compass: dead reckoning)" \
  "$RUNS/pointnav/val/pointnav" "$KC" "$RUNS/pointnav/val/pointnav-habitat-challenge-pointnav-2021"

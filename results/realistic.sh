#!/usr/bin/env bash
# The agents under Habitat's realistic conditions (docs/realistic.md): `bash results/realistic.sh run` makes the
# runs (resumable: run it again to finish them), `... tables` (the default) prints results/realistic.md, `... all`
# does both (`make results-realistic`). NB: the navbench command; RUNS: the runs' root; K: episodes per scene
# (the CPU budget), FK and KC: the same for the frontier agent (about 3 s of CPU an episode) and for the Habitat
# Challenge 2021 PointNav run (640x360, up to 500 steps). A run not made yet is listed as such.
set -u
NB=${NB:-navbench} RUNS=${RUNS:-results/runs} K=${K:-10} FK=${FK:-5} KC=${KC:-2}
CONDITIONS=${CONDITIONS:-"navbench-actuation-x0_5 navbench-actuation-x1 navbench-sensor-noise navbench-all-noise"}
REAL="$NB run --runs-dir $RUNS --resume -q"
runs_all() {
  set -e
  for c in $CONDITIONS; do $REAL --per-scene "$K" --split val_unseen --agent memory --env-config "$c"; done
  for c in $CONDITIONS; do $REAL --per-scene "$K" --task pointnav --split val --env-config "$c"; done
  $REAL --per-scene "$KC" --task pointnav --split val --env-config habitat-challenge-pointnav-2021
  $REAL --per-scene "$KC" --task pointnav --split val --env-config navbench-dead-reckoning
  for c in $CONDITIONS; do $REAL --per-scene "$FK" --split val_unseen --agent frontier --env-config "$c"; done
}
section() {  # section TITLE BASE_RUN PER_SCENE RUN...
  local title=$1 base=$2 k=$3; shift 3
  echo; echo "## $title"; echo
  local have=()
  for r in "$@"; do
    if [ -f "$r/summary.json" ]; then have+=("$r"); else echo "- not run yet: \`$r\` (\`make results-realistic\`)"; fi
  done
  [ ${#have[@]} -eq 0 ] && return
  echo "\`navbench table ${have[*]}\`"; echo
  $NB table "${have[@]}"
  for r in "${have[@]}"; do
    echo; echo "\`navbench compare --mix-protocols --per-scene $k $base $r\`"; echo; echo '```'
    $NB compare --mix-protocols --per-scene "$k" "$base" "$r"; echo '```'
  done
}
tables() {
  local c
  echo "# Realistic conditions: actuation and sensor noise (\`make results-realistic\`)"
  echo
  echo "Each agent under each condition of \`configs/env/\` (docs/realistic.md) on the first $K episodes of each"
  echo "scene ($FK for the frontier agent, $KC for the Habitat Challenge 2021 PointNav run), against its noiseless"
  echo "reference run on the same episodes (paired intervals, noisy minus noiseless). The protocols differ, which"
  echo "is the point, hence \`compare --mix-protocols\`; each table names the conditions that differ in columns. The"
  echo "challenge run also has its own success distance (0.36 m, not 0.2 m)."
  echo "With oracle perception the memory agent and the PointNav policy read depth (and instance ids), not RGB: of"
  echo "the depth+RGB condition only the depth noise reaches them. GPS+compass stay exact (docs/realistic.md)."
  runs() { for c in $CONDITIONS; do echo "$RUNS/$1-$c"; done; }
  section "Memory agent, ObjectNav val_unseen" "$RUNS/objectnav/val_unseen/memory" "$K" \
    $(runs objectnav/val_unseen/memory)
  section "Frontier agent, ObjectNav val_unseen (first $FK episodes of each scene)" \
    "$RUNS/objectnav/val_unseen/frontier" "$FK" \
    $(runs objectnav/val_unseen/frontier)
  section "PointNav policy, PointNav val" "$RUNS/pointnav/val/pointnav" "$K" $(runs pointnav/val/pointnav)
  section "PointNav policy without GPS+compass (dead reckoning): the Habitat Challenge 2021 PointNav configuration, and navbench's conditions without GPS+compass" \
    "$RUNS/pointnav/val/pointnav" "$KC" "$RUNS/pointnav/val/pointnav-habitat-challenge-pointnav-2021" \
    "$RUNS/pointnav/val/pointnav-navbench-dead-reckoning"
}
case ${1:-tables} in
  run) runs_all ;;
  tables) tables ;;
  all) runs_all && tables > results/realistic.md ;;
  *) echo "usage: $0 [run|tables|all]" >&2; exit 2 ;;
esac

#!/usr/bin/env bash
# InstanceImageNav, GOAT-Bench and ImageNav val (docs/tasks.md): `bash results/tasks.sh run` runs the oracle and the
# memory agent on the InstanceImageNav and GOAT-Bench val splits, the frontier agent on all of GOAT-Bench val and on
# InstanceImageNav's first FK episodes of each house (it explores: about 15 s an episode on 2 cores; it is refused on
# ImageNav), the memory agent on ImageNav val with and without its look round at the goal (--no-look-round; the
# oracle's ImageNav run is make results-oracle's), `... tables`
# writes results/instance_imagenav.md, results/goat.md and results/imagenav.md, `... all` does both (`make
# results-tasks`). NB: the navbench command; PY: the Python that runs navbench.eval.goat_table; RUNS: the runs' root;
# LIMIT=N: the first N episodes of each split only (a quick look).
set -eu
NB=${NB:-navbench} PY=${PY:-python} RUNS=${RUNS:-results/runs} LIMIT=${LIMIT:-} FK=${FK:-25}
runs_all() {
  for t in instance_imagenav goat; do for a in oracle memory; do
    $NB run --runs-dir "$RUNS" --overwrite -q --task $t --split val --agent $a ${LIMIT:+--limit $LIMIT}
  done; done
  $NB run --runs-dir "$RUNS" --overwrite -q --task goat --split val --agent frontier ${LIMIT:+--limit $LIMIT}
  $NB run --runs-dir "$RUNS" --overwrite -q --task instance_imagenav --split val --agent frontier --per-scene "$FK" \
    ${LIMIT:+--limit $LIMIT}
  $NB run --runs-dir "$RUNS" --overwrite -q --task imagenav --split val --agent memory ${LIMIT:+--limit $LIMIT}
  $NB run --runs-dir "$RUNS" --overwrite -q --task imagenav --split val --agent memory --no-look-round \
    ${LIMIT:+--limit $LIMIT}
}
shown() {  # shown COMMAND...: the command, then what it prints
  echo "\`$*\`" | sed "s#^\`$NB #\`navbench #; s#^\`$PY #\`python #"; echo; "$@"
}
tables() {
  local i=$RUNS/instance_imagenav/val g=$RUNS/goat/val
  { echo "# InstanceImageNav val (\`make results-tasks\`)"; echo
    shown $NB table "$i/oracle" "$i/memory" "$i/frontier"; echo
    echo "Paired on the episodes both ran (the first $FK of each house): \`navbench compare --per-scene $FK" \
      "$i/frontier $i/memory\`"; echo; echo '```'; $NB compare --per-scene "$FK" "$i/frontier" "$i/memory"
    echo '```'; echo
    shown $NB table --long "$i/oracle" "$i/memory"; } > results/instance_imagenav.md
  { echo "# GOAT-Bench val (\`make results-tasks\`)"; echo
    echo "These runs use navbench's body (the task's default configuration: camera 0.88 m above the floor, 224 x 224" \
      "RGB-D, 79° HFOV, GPS+compass, 30° turns, 5000 steps), not GOAT-Bench's (\`--env-config goat-bench\`:" \
      "camera 1.41 m, 360 x 640 portrait, 42° HFOV), so they are not GOAT-Bench's own figures."; echo
    shown $NB table "$g/oracle" "$g/memory" "$g/frontier"; echo
    echo "Paired by episode: \`navbench compare $g/frontier $g/memory\`"; echo
    echo '```'; $NB compare "$g/frontier" "$g/memory"; echo '```'; echo
    shown $PY -m navbench.eval.goat_table "$g/oracle" "$g/memory" "$g/frontier"; } > results/goat.md
  local m=$RUNS/imagenav/val
  { echo "# ImageNav val (\`make results-tasks\`; the oracle's run: \`make results-oracle\`)"; echo
    shown $NB table "$m/oracle" "$m/memory" "$m/memory-nolookround"; echo
    echo "Paired on the episodes both ran: \`navbench compare $m/memory $m/oracle\`"; echo
    echo '```'; $NB compare "$m/memory" "$m/oracle"; echo '```'; echo
    echo "What its look round at the goal adds, paired by episode: \`navbench compare $m/memory-nolookround" \
      "$m/memory\`"; echo
    echo '```'; $NB compare "$m/memory-nolookround" "$m/memory"; echo '```'; echo
    echo "How far the goal-camera estimates (before any look round) fell from where the goal images were taken (xz)," \
      "all 400 episodes:"; echo
    shown $PY -m navbench.eval.imagegoal_errors "$m/memory-nolookround"; } > results/imagenav.md
}
case "${1:-tables}" in
  run) runs_all ;;
  tables) tables ;;
  all) runs_all; tables ;;
  *) echo "usage: bash results/tasks.sh [run|tables|all]" >&2; exit 2 ;;
esac

#!/usr/bin/env bash
# VLN-CE's baselines on navbench's bundled R2R-CE-style split (episodes/r2r_ce/val, `navbench generate vlnce`):
# `make results-vlnce` runs them into RUNS and prints results/vlnce.md. NB: the navbench command; RUNS: the runs'
# root. The random and forward-only agents run under VLN-CE's own R2R-CE configuration (r2r-ce); the oracle, which
# knows its pose, under navbench-r2r-ce (the same plus GPS+compass, which no measure reads).
set -eu
NB=${NB:-navbench} RUNS=${RUNS:-results/runs}
RUN="$NB run --runs-dir $RUNS --overwrite -q --task r2r_ce --split val"
D=$RUNS/r2r_ce/val
$RUN --agent vln_random >&2
$RUN --agent vln_forward >&2
$RUN --agent vln_oracle --env-config navbench-r2r-ce >&2
echo '# VLN-CE baselines on the bundled R2R-CE-style split: `make results-vlnce`'
echo
echo "400 episodes (100 routes in each of the 4 val houses), R2R-CE's configuration (configs/env/r2r-ce.toml: 15 degree"
echo "turns, sliding, 500 steps, success within 3.0 m) and VLN-CE's measures as its code computes them (docs/tasks.md):"
echo "TL and NE in metres, the others in percent, each with its 95% interval (houses, then episodes)."
echo
for r in vln_random vln_forward vln_oracle-navbench-r2r-ce; do
  case $r in
    vln_oracle*) cmd="navbench run --task r2r_ce --split val --agent vln_oracle --env-config navbench-r2r-ce" ;;
    *) cmd="navbench run --task r2r_ce --split val --agent $r" ;;
  esac
  echo "\`$cmd\`"; echo
  $NB table --long "$D/$r"; echo
done
echo 'The oracle follows the reference path through its ~2 m viewpoints with the same follower that wrote the gt paths,'
echo 'so its nDTW is near 100 by construction; its SPL is below 100 because a route through a landmark in a third room'
echo 'is longer than the start-to-goal geodesic SPL compares with. `vln_random` and `vln_forward` are VLN-CE'"'"'s own'
echo 'RandomAgent and HandcraftedAgent (vlnce_baselines/nonlearning_agents.py).'

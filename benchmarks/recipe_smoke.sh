#!/usr/bin/env bash
# Smoke of a training recipe's resumability: start one stage, stop it with SIGTERM after its first logged update,
# resume it, stop it again after the next one. Prints the log rows and the resume lines.
#
#     benchmarks/recipe_smoke.sh pointnav/v2 dagger_own_states policies/pointnav_navbench.pth [OUT_DIR]
#     PREV_STAGE=dagger_quarter_lr benchmarks/recipe_smoke.sh full ppo_bc policies/pointnav_navbench.pth
#
# A later stage starts from the previous stage's output: PREV_STAGE names it, and INIT is copied there.
set -euo pipefail
recipe=$1 stage=$2 init=$3 out=${4:-runs/smoke_${2}}
rm -rf "$out"
log="$out/$stage.log.csv"
rows_logged() { if [ -f "$log" ]; then echo $(($(wc -l < "$log") - 1)); else echo 0; fi; }
run_until_rows() {  # run the stage (extra args: --resume) until its log has $1 more data rows, then SIGTERM it
    local rows=$(($(rows_logged) + $1)); shift
    navbench_cmd=(python -m navbench train --config "$recipe" --init "$init" --only "$stage" --out-dir "$out" "$@")
    NAVBENCH_PROGRESS=0 "${navbench_cmd[@]}" > "$out.stdout" 2>&1 &
    local pid=$! t0=$SECONDS
    until [ "$(rows_logged)" -ge "$rows" ]; do
        kill -0 $pid 2>/dev/null || { cat "$out.stdout"; exit 1; }
        sleep 1
    done
    kill -TERM $pid
    wait $pid || true
    echo "--- ${navbench_cmd[*]}: stopped after $((SECONDS - t0)) s"
    grep -E "resumed|stopped by signal|initialised" "$out.stdout" || true
}
mkdir -p "$out"
if [ -n "${PREV_STAGE:-}" ]; then cp "$init" "$out/$PREV_STAGE.pth"; fi
run_until_rows 1
run_until_rows 1 --resume
cut -d, -f1-3 "$log"

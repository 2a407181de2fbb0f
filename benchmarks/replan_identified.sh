#!/usr/bin/env bash
# Re-plan every example and held-out task for robots identified on virtual prototypes
# (BENCHMARKS.md, "Re-plans for identified robots").  Usage, from the repository:
#   SEEDS="3101 3102 3103" HELDOUT="HO/*.yaml" bash benchmarks/replan_identified.sh OUT
# HELDOUT: held-out task files (e.g. bench_planner_heldout.py's generator's, written as
# YAML); one line per plan: seed, task, the plan's exit code, whether it planned again.
set -u
S=.venv/bin/sixplus3
W=${1:-out/replan_identified}; mkdir -p "$W"
[ -f "$W/ident/excitation.csv" ] || $S identify excite -o "$W/ident" > "$W/excite.log" 2>&1
for seed in ${SEEDS:-3101 3102 3103}; do
  o=$W/s$seed; mkdir -p "$o"
  $S identify plant -o "$o/plant.yaml" --seed "$seed" > /dev/null
  $S simulate "$W/ident/excitation.csv" --plant "$o/plant.yaml" --log "$o/exc.csv" \
      --force > /dev/null
  if ! $S identify estimate "$o/exc.csv" -o "$o/identified.yaml" --force \
      > "$o/estimate.log" 2>&1; then
    echo "$seed not identified: $(tail -1 "$o/estimate.log")"; continue
  fi
  for t in gentle_translate translate tilt30_x tilt30_y tilt60_x tilt60_y tilt_large_x \
           tilt_large_y torsion_z combined ceiling_handle ${HELDOUT:-}; do
    name=$(basename "$t" .yaml)
    $S --robot "$o/identified.yaml" plan "$t" -o "$o/plans" --no-html \
        > "$o/plan_$name.log" 2>&1
    echo "$seed $name rc=$? again=$(grep -c 'planning again' "$o/plan_$name.log")"
  done
done

#!/usr/bin/env bash
# A new user's first run (BENCHMARKS.md, "First run"): a fresh clone of this repository,
# pip's and sixplus3's caches empty (HOME a new folder), then `make demo`, then the
# interaction commands twice each (first against second run), then the controllers'
# builds.  Usage: bash benchmarks/first_run.sh   (from the repository; minutes)
set -u
src=$(git rev-parse --show-toplevel)
export HOME=$(mktemp -d /tmp/home.XXXX)
d=$(mktemp -d /tmp/fresh.XXXX); git clone -q "$src" "$d"; cd "$d"
echo "HOME=$HOME clone=$d nproc=$(nproc) $(date)"
/usr/bin/time -f "make demo: wall %e s, user %U s, sys %S s" make demo > demo.log 2> demo.err
tail -1 demo.err; grep -c . demo.log
grep -v "Location '" demo.err | grep -iv "^make demo" | head -5
S=.venv/bin/sixplus3
T() { /usr/bin/time -f "$1: wall %e s, cpu %U+%S s" "${@:2}" > /dev/null 2>> times.txt; }
$S identify plant -o plant.yaml --seed 3 > /dev/null
$S plan gentle_translate -o pl --no-html > /dev/null
$S simulate pl/gentle_translate.csv --plant plant.yaml --log val.csv --hold 1 > /dev/null
$S commission jog --plant plant.yaml -o jog.csv > /dev/null
for i in 1 2; do
  T "wrench $i" $S wrench val.csv -o w$i.csv
  T "identify check $i" $S identify check val.csv
  T "commission directions $i" $S commission directions jog.csv -o r$i.yaml
done
cat times.txt
.venv/bin/python - <<'PY'
import time
from sixplus3.robot_description.robot import Robot
from sixplus3.interaction.leadthrough import LeadThrough
from sixplus3.interaction.guard import ContactGuard
r = Robot.default()
for k in (1, 2):
    t0 = time.perf_counter(); LeadThrough(r, 1000.0, drive_gains=(300.0, 6.0)); t1 = time.perf_counter()
    ContactGuard(r, "pl/gentle_translate.csv", drive_gains=(3000.0, 30.0)); t2 = time.perf_counter()
    print(f"build {k}: LeadThrough {t1 - t0:.2f} s, ContactGuard {t2 - t1:.2f} s")
PY
/usr/bin/time -f "make demo again: wall %e s" make demo > /dev/null 2> again.err; tail -1 again.err
echo "end $(date)"

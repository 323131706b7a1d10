#!/bin/sh
# Issue 15, scale-out: one solve on 1 process x 1 thread, 2 processes x 1 thread (mpirun) and
# 1 process x 2 threads, interleaved REPS times; prints each run's shooting time, wall time and
# bytes summed per round, then the medians and the parallel efficiencies (model.py models more
# processes from these figures).
#   FLATLAND  binary (default: build/flatland)
#   SCENES    scene files (default: scenes2d/default.json scenes2d/curved_room.json)
#   PHOTONS   budget (default 1e7; tolerance 1e-9, so the budget is spent)
#   REPS      repetitions (default 5)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
FLATLAND=${FLATLAND:-$root/build/flatland}
SCENES=${SCENES:-"$root/scenes2d/default.json $root/scenes2d/curved_room.json"}
PHOTONS=${PHOTONS:-1e7}
REPS=${REPS:-5}
MPIRUN=${MPIRUN:-mpirun}
# OpenMPI refuses root unless told; harmless otherwise.
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

log=$(mktemp)
trap 'rm -f "$log"' EXIT
for scene in $SCENES; do
    for rep in $(seq "$REPS"); do
        for config in "1 1" "2 1" "1 2"; do
            set -- $config
            if [ "$1" -eq 1 ]; then launcher=""; else launcher="$MPIRUN --oversubscribe -np $1"; fi
            start=$(date +%s.%N)
            out=$($launcher "$FLATLAND" solve "$scene" --photons "$PHOTONS" --tolerance 1e-9 --threads "$2")
            end=$(date +%s.%N)
            shooting=$(echo "$out" | sed -n 's/^solved .* rounds, \([0-9.]*\) s,.*/\1/p')
            rounds=$(echo "$out" | sed -n 's/^solved .* in \([0-9]*\) rounds.*/\1/p')
            bytes=$(echo "$out" | sed -n 's/^shared .* summed \([^ ]*\) bytes per round.*/\1/p')
            echo "$(basename "$scene") $1 $2 $shooting $(echo "$end - $start" | bc) $rounds ${bytes:--}" | tee -a "$log"
        done
    done
done
echo
python3 - "$log" <<'PY'
import statistics, sys
# Efficiencies are medians over repetitions of ratios within one repetition (the three runs of a
# repetition follow each other): this VM's speed drifts by 1.5x within minutes.
runs = {}
for line in open(sys.argv[1]):
    scene, p, t, shoot, wall, rounds, per_round = line.split()
    runs.setdefault((scene, int(p), int(t)), []).append((float(shoot), float(wall), int(rounds), per_round))
print("| scene | processes x threads | shooting (median) | wall (median) | rounds | summed per round | efficiency, shooting | efficiency, wall |")
print("|---|---|---|---|---|---|---|---|")
for scene in dict.fromkeys(k[0] for k in runs):
    one = runs[(scene, 1, 1)]
    for p, t in ((1, 1), (2, 1), (1, 2)):
        rs = runs[(scene, p, t)]
        n = p * t
        shooting = statistics.median(a[0] / (n * b[0]) for a, b in zip(one, rs))
        wall = statistics.median(a[1] / (n * b[1]) for a, b in zip(one, rs))
        print(f"| {scene} | {p} x {t} | {statistics.median(r[0] for r in rs):.3f} s | "
              f"{statistics.median(r[1] for r in rs):.3f} s | {rs[0][2]} | {rs[0][3]} | {shooting:.2f} | {wall:.2f} |")
PY

#!/bin/sh
# Issue 12, part 5: time to accuracy. Solves every method at every photon budget and seed on five
# scenes (flatland converge), then prints the table (analyse.py) and draws the plots (plot.gp).
# Reduced settings by default (3 seeds); the issue's full run is SEEDS=5 run.sh.
#   FLATLAND  binary (default: build/flatland; the 2026-12-02 run used a copy of it)
#   SEEDS     seeds per method and budget (default 3; the issue asks for 5)
#   BUDGETS   photon budgets (default 1e4,3e4,1e5,3e5,1e6,3e6,1e7)
#   THREADS   solver threads (default 2)
#   SCENES    which scenes (default: all five, names as below)
#   EXTEND    extra budgets (default 3e7) for linear and cubic with the random sampler on EXTEND_SCENES
#             (default: penumbra round_occluder), to measure rather than extrapolate their time to 0.1 %;
#             EXTEND= skips them
#   MAIN      MAIN=0 skips the main measurement (only the extension, the table and the plots)
set -eu
root=$(cd "$(dirname "$0")/../../.." && pwd)
FLATLAND=${FLATLAND:-$root/build/flatland}
# From the repository's top, with paths relative to it: what the programs print (and the logs
# kept here) names no directory of the machine that ran them.
cd "$root"
here=docs/figures/time_to_accuracy
SEEDS=${SEEDS:-3}
BUDGETS=${BUDGETS:-1e4,3e4,1e5,3e5,1e6,3e6,1e7}
THREADS=${THREADS:-2}
SCENES=${SCENES:-"penumbra round_occluder lit_ring ring_profile curved_room"}
EXTEND=${EXTEND-3e7}
EXTEND_SCENES=${EXTEND_SCENES:-"penumbra round_occluder"}
MAIN=${MAIN:-1}
export BUDGETS EXTEND THREADS

scene_file() {
    case "$1" in
        penumbra)       echo scenes2d/penumbra.json ;;
        round_occluder) echo scenes2d/tests/reference_round_occluder.json ;;
        lit_ring)       python3 "$here/make_lit_ring.py" >/dev/null; echo "$here/lit_ring.json" ;;
        ring_profile)   echo scenes2d/tests/reference_ring_profile.json ;;
        curved_room)    echo scenes2d/curved_room.json ;;
        *) echo "unknown scene $1" >&2; exit 1 ;;
    esac
}

classic=basis=constant+sampling=uniform+discontinuities=none+estimator=lumped
methods=""
for s in random sobol; do
    for m in $classic basis=linear basis=cubic basis=hermite; do
        methods="$methods${methods:+,}$m+sampler=$s"
    done
done

[ "$MAIN" = 1 ] || SCENES=""
for name in $SCENES; do
    scene=$(scene_file "$name")
    out="$here/$name"
    mkdir -p "$out"
    [ -f "$out/reference.json" ] || "$FLATLAND" reference "$scene" --threads "$THREADS" --out "$out/reference.json" | tee "$out/reference.txt"
    start=$(date +%s)
    "$FLATLAND" converge "$scene" --reference "$out/reference.json" --methods "$methods" \
        --budgets "$BUDGETS" --seeds "$SEEDS" --threads "$THREADS" --out "$out" > "$out/converge.txt"
    echo "$name: $(( $(date +%s) - start )) s" | tee -a "$here/wall_times.txt"
done
if [ -n "$EXTEND" ]; then
    for name in $EXTEND_SCENES; do
        scene=$(scene_file "$name")
        out="$here/$name/extend"
        mkdir -p "$out"
        start=$(date +%s)
        "$FLATLAND" converge "$scene" --reference "$here/$name/reference.json" \
            --methods basis=linear+sampler=random,basis=cubic+sampler=random \
            --budgets "$EXTEND" --seeds "$SEEDS" --threads "$THREADS" --out "$out" > "$out/converge.txt"
        echo "$name, extension $EXTEND: $(( $(date +%s) - start )) s" | tee -a "$here/wall_times.txt"
    done
fi
python3 "$here/analyse.py" "$here" | tee "$here/table.md"

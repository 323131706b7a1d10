#!/bin/sh
# Issue 14, part 3: random walks against progressive shooting, error against time. Solves cubic
# storage (the defaults: auto elements, Galerkin, reconstructed origins, Sobol') by both transports
# at every budget and seed on five scenes (flatland converge), then prints the table (table.py).
#   FLATLAND  binary (default: build/flatland)
#   SEEDS     seeds per method and budget (default 3)
#   BUDGETS   photons (shooting) or walks (walk) (default 1e4,3e4,1e5,3e5,1e6,3e6,1e7)
#   THREADS   solver threads (default 1: pin the run to one core with taskset for steady times)
#   SCENES    which scenes (default: all five, names as below)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
FLATLAND=${FLATLAND:-$root/build/flatland}
SEEDS=${SEEDS:-3}
BUDGETS=${BUDGETS:-1e4,3e4,1e5,3e5,1e6,3e6,1e7}
THREADS=${THREADS:-1}
SCENES=${SCENES:-"penumbra round_occluder lit_ring ring_profile curved_room"}

scene_file() {
    case "$1" in
        penumbra)       echo "$root/scenes2d/penumbra.json" ;;
        round_occluder) echo "$root/scenes2d/tests/reference_round_occluder.json" ;;
        lit_ring)       python3 "$root/docs/figures/time_to_accuracy/make_lit_ring.py" >/dev/null
                        echo "$root/docs/figures/time_to_accuracy/lit_ring.json" ;;
        ring_profile)   echo "$root/scenes2d/tests/reference_ring_profile.json" ;;
        curved_room)    echo "$root/scenes2d/curved_room.json" ;;
        *) echo "unknown scene $1" >&2; exit 1 ;;
    esac
}

cd "$root"
for name in $SCENES; do
    scene=$(scene_file "$name")
    out="$here/$name"
    mkdir -p "$out"
    [ -f "$out/reference.json" ] || "$FLATLAND" reference "$scene" --threads "$THREADS" --out "$out/reference.json" > "$out/reference.txt"
    "$FLATLAND" converge "$scene" --reference "$out/reference.json" \
        --methods basis=cubic+transport=shooting,basis=cubic+transport=walk \
        --budgets "$BUDGETS" --seeds "$SEEDS" --threads "$THREADS" --out "$out" > "$out/converge.txt"
done
python3 "$here/table.py" "$here" | tee "$here/table.md"

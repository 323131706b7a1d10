#!/usr/bin/env bash
# The matrix of solves that says whether a change kept every result's bits: eight scenes (lines,
# cubics, colour, closed curves, contacts) x thirteen settings (every basis and estimator, both
# samplers, every transport, replicates as blocks, footprints, bands, secondary events with uniform
# origins, the control variate off; the default, auto, takes it wherever the others allow), then
# MPI with two processes and Python on three scenes: 110 result documents, written without what may
# differ between runs of the same solve (timings, thread and process counts, the program's version
# and commit).
#
# Usage: tests/identity_matrix.sh OUT_DIR            (with build/flatland and build/python)
#        FLATLAND=path/to/flatland PYTHONPATH=path/to/python tests/identity_matrix.sh OUT_DIR
# Then:  diff -r BEFORE_DIR AFTER_DIR && echo "bit-identical"
# A change of a default is compared with the old default given to both builds: EXTRA (words added
# to every CLI solve, e.g. "--control-variate none") and PYTHON_EXTRA (keyword=value words added
# to every Python solve, e.g. "control_variate=none").
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:?usage: tests/identity_matrix.sh OUT_DIR}
flatland=${FLATLAND:-build/flatland}
python_path=${PYTHONPATH:-build/python}
python=$(command -v /usr/bin/python3 || command -v python3)
mkdir -p "$out"

scenes=(penumbra default curved_room mixed arch enclosure syndrome room_reflector)
settings=(
  ""
  "--sampler random"
  "--basis linear --elements 32"
  "--basis constant --estimator lumped --elements 16"
  "--basis hermite"
  "--estimator local"
  "--transport walk"
  "--ray-width 0.02"
  "--ray-width 0.02 --ray-mode band --band-rays 4"
  "--discontinuities secondary --sampling uniform"
  "--transport jacobi"
  "--replicate-layout blocks"
  "--control-variate none"
)
extra=${EXTRA:-}

# Drops what may differ between runs of the same solve, and writes the rest with sorted keys.
normalise() {
  "$python" -c '
import json, sys
document = json.load(open(sys.argv[1]))
document.get("stats", {}).pop("seconds", None)
for key in ("threads", "processes"):
    document.get("settings", {}).pop(key, None)
document.pop("program", None)
json.dump(document, open(sys.argv[1], "w"), indent=1, sort_keys=True)
' "$1"
}

count=0
for scene in "${scenes[@]}"; do
  for i in "${!settings[@]}"; do
    file="$out/$scene-$i.json"
    # EXTRA's option is left out where the row sets it itself.
    row_extra=$extra
    if [[ -n $extra && "${settings[$i]}" == *"${extra%% *}"* ]]; then row_extra=""; fi
    # shellcheck disable=SC2086 # the settings are words
    "$flatland" solve "scenes2d/$scene.json" --photons 2e5 --seed 3 --threads 2 --samples 50 \
      ${settings[$i]} $row_extra --quiet --out "$file"
    normalise "$file"
    count=$((count + 1))
  done
done

export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
if command -v mpirun >/dev/null; then
  for scene in mixed default curved_room; do
    file="$out/mpi-$scene.json"
    mpirun --oversubscribe -np 2 "$flatland" solve "scenes2d/$scene.json" --photons 2e5 --seed 3 --threads 1 \
      --samples 50 $extra --quiet --out "$file"
    normalise "$file"
    count=$((count + 1))
  done
fi

for scene in syndrome arch enclosure; do
  file="$out/python-$scene.json"
  PYTHONPATH=$python_path "$python" -c '
import sys, flatland
scene = flatland.Scene.load(sys.argv[1])
extra = dict(word.split("=", 1) for word in sys.argv[3].split())
solved = flatland.solve(scene, photons=200_000, seed=3, threads=2, ray_width=0.01, **extra)
open(sys.argv[2], "w").write(solved.to_json(samples=50))
' "scenes2d/$scene.json" "$file" "${PYTHON_EXTRA:-}"
  normalise "$file"
  count=$((count + 1))
done
echo "identity matrix: $count result documents in $out"

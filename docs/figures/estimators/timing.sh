#!/usr/bin/env bash
# Solve time of each estimator, interleaved (lumped, galerkin, local, lumped, ...) so that a load
# that drifts on a shared machine falls on all three alike; 1e7 photons, 2 threads, seed 1.
# Prints: scene basis elements estimator repetition seconds (the solve's own stats.seconds). ~1 minute.
# Usage: [FLATLAND=build/flatland] [REPS=2] docs/figures/estimators/timing.sh
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-build/flatland}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for config in "penumbra cubic 16" "penumbra hermite 64" "curved_room cubic 16" "curved_room hermite 16"; do
  read -r scene basis n <<<"$config"
  for rep in $(seq 1 "${REPS:-2}"); do
    for estimator in lumped galerkin local; do
      "$flatland" solve "scenes2d/$scene.json" --basis "$basis" --estimator "$estimator" --elements "$n" \
        --photons 1e7 --tolerance 1e-6 --threads 2 --quiet --out "$tmp/r.json"
      echo "$scene $basis $n $estimator $rep $(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["stats"]["seconds"])' "$tmp/r.json")"
    done
  done
done

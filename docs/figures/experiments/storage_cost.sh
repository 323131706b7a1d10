#!/usr/bin/env bash
# Experiment 3 of docs/experiments.md: run time against the size of the storage mesh. Solves
# scenes2d/room_reflector.json with a fixed photon count (the whole budget is spent: tolerance
# 1e-9) at storage meshes of 1 .. 2047 elements per curve, cubic basis, `scene` discontinuities,
# one thread, SEEDS seeds each, and prints the median seconds (with their interquartile range) and the coefficients per curve.
# Needs build/flatland and python3.
# Usage: docs/figures/experiments/storage_cost.sh [PHOTONS] [SEEDS]
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-build/flatland}
# So that a change of the program's defaults does not change what this measures, what the experiment does not vary is pinned to the defaults (cubic, Galerkin, reconstructed origins, Sobol' points, point rays).
pin=(--basis cubic --estimator galerkin --sampling reconstructed --sampler sobol --ray-width 0 --transport shooting --gather none --control-variate none)
photons=${1:-2e6}
seeds=${2:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for n in 1 3 15 63 255 1023 2047; do
  for seed in $(seq 1 "$seeds"); do
    "$flatland" solve "${pin[@]}" scenes2d/room_reflector.json --photons "$photons" --elements "$n" \
      --discontinuities scene --seed "$seed" --tolerance 1e-9 --threads 1 --quiet \
      --out "$work/e$n-s$seed.json"
  done
done
python3 - "$work" "$seeds" <<'PY'
import glob, json, os, statistics, sys
sys.path.insert(0, os.path.join("docs", "figures"))
import spread
work, seeds = sys.argv[1], int(sys.argv[2])
print("Solve seconds, the %s:\n" % spread.caption(seeds))
print("| `--elements` | coefficients per curve | rounds | seconds |")
print("|---|---|---|---|")
for n in (1, 3, 15, 63, 255, 1023, 2047):
    seconds, rounds, coefficients = [], set(), set()
    for seed in range(1, seeds + 1):
        with open(os.path.join(work, "e%d-s%d.json" % (n, seed))) as f:
            r = json.load(f)
        seconds.append(r["stats"]["seconds"])
        rounds.add(r["stats"]["rounds"])
        for c in r["curves"]:
            coefficients.add(len(c["coefficients"]))
    print("| %d | %d-%d | %s | %s |" % (n, min(coefficients), max(coefficients),
          "/".join(str(x) for x in sorted(rounds)), spread.cell(seconds, lambda v: "%.3f" % v)))
PY

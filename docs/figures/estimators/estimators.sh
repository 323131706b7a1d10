#!/usr/bin/env bash
# The estimators measured (docs/method.md, "Estimators: measured"). SLOW: with the defaults below
# 324 solves per scene, 1296 in all: 32 minutes on 2 cores shared with another job (2026-12-02),
# most of it in the 1e7-photon runs. The solver settings other than those varied are pinned to the
# defaults of the build measured (commit e44666b), so later changes of defaults do not move them.
#
# For each scene a reference (flatland reference, N = 800 elements across the scene, 100 samples
# per curve), then for every basis (constant, linear, cubic, hermite), estimator (lumped, galerkin,
# local), storage size (--elements 16, 64, 256), photon budget (1e5, 1e6, 1e7) and seed (1..SEEDS)
# one `flatland solve --tolerance 1e-6` (so that the whole budget is shot) with --out; then
# analyse.py computes each run's relative L2 error of B - E against the reference (the same number as
# `flatland compare RESULT REF`, which it checks on the first run), the median over seeds, the error
# of the seeds' mean, and a bias / noise split, and writes runs.csv, summary.csv and tables.md here.
#
# Usage: [FLATLAND=build/flatland] [SEEDS=3] [ELEMENTS="16 64 256"] [BUDGETS="1e5 1e6 1e7"]
#        [THREADS=2] [WORK=dir] docs/figures/estimators/estimators.sh [SCENE...]
# SCENE is a path under scenes2d/ without .json (default: the four below). The results (one JSON per
# run) stay in WORK (default /tmp/flatland-estimators); rerunning skips runs whose JSON exists.
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-build/flatland}
seeds=${SEEDS:-3}
elements=${ELEMENTS:-16 64 256}
budgets=${BUDGETS:-1e5 1e6 1e7}
threads=${THREADS:-2}
work=${WORK:-/tmp/flatland-estimators}
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(penumbra tests/reference_round_occluder tests/reference_ring_profile curved_room)
mkdir -p "$work"
for scene in "${scenes[@]}"; do
  name=$(basename "$scene")
  ref=$work/$name-reference.json
  [ -f "$ref" ] || "$flatland" reference "scenes2d/$scene.json" --elements 1600 --threads "$threads" \
    --quiet --out "$ref"
  for basis in constant linear cubic hermite; do
    for estimator in lumped galerkin local; do
      for n in $elements; do
        for photons in $budgets; do
          for seed in $(seq 1 "$seeds"); do
            out=$work/$name/$basis-$estimator-e$n-p$photons-s$seed.json
            [ -f "$out" ] || [ -f "${out%.json}.failed" ] && continue
            mkdir -p "$work/$name"
            # A solve that fails leaves RUN.failed (its message) and the table says "fails".
            "$flatland" solve "scenes2d/$scene.json" --basis "$basis" --estimator "$estimator" \
              --elements "$n" --photons "$photons" --seed "$seed" --tolerance 1e-6 \
              --sampling reconstructed --discontinuities auto --sampler random --ray-width 0 --transport shooting --gather none --control-variate none \
              --threads "$threads" --quiet --out "$out" 2>"$work/stderr" ||
              cp "$work/stderr" "${out%.json}.failed"
          done
        done
      done
    done
  done
done
python3 docs/figures/estimators/analyse.py --flatland "$flatland" --work "$work" \
  --out docs/figures/estimators "${scenes[@]}"

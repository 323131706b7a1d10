#!/usr/bin/env bash
# Experiment 1 of docs/experiments.md: error against run time, in three groups per scene: the
# storage (constant, linear, cubic B-splines and cubic Hermite, reconstructed origins), the photon
# origins (uniform in arc length against following the reconstruction, for constant and cubic
# storage), and the rays (point, footprints of width 0.01 and 0.05 m, a band of 8 sub-rays of
# width 0.05 m; cubic storage), with ELEMENTS (32) storage elements per curve. For each scene a reference (N = 800,
# 200 samples per curve, with its own error estimate), then flatland converge over photon budgets
# 1e4 .. 1e7 and SEEDS seeds. Writes docs/figures/experiments/SCENE/eELEMENTS/GROUP/convergence.{csv,png,svg}.
# Needs build/flatland and gnuplot.
# THREADS=N passes --threads N to every solve (default: all cores).
# Usage: [ELEMENTS=N] [THREADS=N] docs/figures/experiments/error_vs_time.sh [SEEDS] [SCENES...]
set -euo pipefail
cd "$(dirname "$0")/../../.."
seeds=${1:-5}
elements=${ELEMENTS:-32}
threads=(${THREADS:+--threads "$THREADS"})
shift || true
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(penumbra curved_room room_reflector syndrome)
declare -A groups=(
  [storage]="constant,linear,cubic,hermite"
  [origins]="constant+sampling=uniform,constant,cubic+sampling=uniform,cubic"
  [rays]="cubic,cubic+ray-width=0.01,cubic+ray-width=0.05,cubic+ray-width=0.05+ray-mode=band"
)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for scene in "${scenes[@]}"; do
  build/flatland reference "scenes2d/$scene.json" --elements 800 --samples 200 --quiet "${threads[@]}" \
    --out "$work/$scene-reference.json"
  for group in storage origins rays; do
    out=docs/figures/experiments/$scene/e$elements/$group
    mkdir -p "$out"
    build/flatland converge "scenes2d/$scene.json" --reference "$work/$scene-reference.json" \
      --methods "${groups[$group]}" --elements "$elements" --budgets 1e4,3e4,1e5,3e5,1e6,3e6,1e7 \
      --seeds "$seeds" --samples 200 "${threads[@]}" --out "$out"
    rm -f "$out/convergence.gp" "$out/convergence.dat"
  done
done

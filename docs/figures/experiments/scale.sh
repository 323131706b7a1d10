#!/usr/bin/env bash
# Experiment 6b of docs/experiments.md: extreme scales and far coordinates. The curved room as it
# is, scaled by 1e-6 and 1e6, and moved to (1e6, 1e6) and (1e8, -1e8)
# (scenes2d/experiments/curved_room_*.json, made by make_scenes.py). B per unit length does not
# change under these maps, so every variant must give the curved room's B within the Monte Carlo
# error. For each: a reference of its own (N = 800), and SEEDS solves of PHOTONS photons; prints
# the reference's difference from the original's reference, each variant's median relative L2
# error against the original's reference, the same-seed difference from the original's solve, and
# the original's own seed-to-seed noise for scale. Samples are matched by index (same arc-length
# fractions), since flatland compare refuses curves of other lengths.
# Needs build/flatland and python3. Usage: docs/figures/experiments/scale.sh [PHOTONS] [SEEDS]
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-build/flatland}
# So that a change of the program's defaults does not change what this measures, every other setting is pinned to the defaults (cubic, Galerkin, auto mesh, Sobol' points).
pin=(--basis cubic --estimator galerkin --elements auto --sampling reconstructed --discontinuities auto --sampler sobol --ray-width 0 --transport shooting --gather none --control-variate none --threads 2)
photons=${1:-1000000}
seeds=${2:-5}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
variants="curved_room experiments/curved_room_scale1e-6 experiments/curved_room_scale1e6 experiments/curved_room_far1e6 experiments/curved_room_far1e8"
for v in $variants; do
  name=$(basename "$v")
  # The original's reference estimates its own error (checked against the errors it judges); the
  # variants' references are compared with it, not with a truth.
  estimate=(--no-error-estimate)
  [ "$name" != curved_room ] || estimate=()
  "$flatland" reference "scenes2d/$v.json" --elements 1600 --samples 200 --quiet "${estimate[@]}" \
    --out "$work/$name-reference.json"
  for seed in $(seq 1 "$seeds"); do
    "$flatland" solve "${pin[@]}" "scenes2d/$v.json" --photons "$photons" --tolerance 1e-6 --seed "$seed" \
      --samples 200 --quiet --out "$work/$name-$seed.json"
  done
done
python3 - "$work" "$seeds" "$variants" <<'PY'
import os, sys
sys.path.insert(0, os.path.join("docs", "figures", "experiments"))
from analysis import load, samples, l2, bias_and_noise, median, reference_check
sys.path.insert(0, os.path.join("docs", "figures"))
import spread
work, seeds, variants = sys.argv[1], int(sys.argv[2]), [os.path.basename(v) for v in sys.argv[3].split()]
def values(name):
    result = load(os.path.join(work, name + ".json"))
    v, _ = samples(result)
    # Weights relative to the curve lengths of the original, so the norms are comparable.
    return v, result
reference, weights = samples(load(os.path.join(work, "curved_room-reference.json")))
original = [samples(load(os.path.join(work, "curved_room-%d.json" % s)))[0] for s in range(1, seeds + 1)]
_, noise = bias_and_noise(original, reference, weights)
print("seed-to-seed noise of the original (one run, relative L2): %.2e\n" % noise)
print("Each variant's %s:\n" % spread.caption(seeds))
print("| scene | its reference vs the original's | rel. L2 error vs reference | same seed vs original | photons/s |")
print("|---|---|---|---|---|")
smallest = 1.0
for name in variants:
    own_reference = samples(load(os.path.join(work, name + "-reference.json")))[0]
    errors, differences, rates = [], [], []
    for seed in range(1, seeds + 1):
        result = load(os.path.join(work, "%s-%d.json" % (name, seed)))
        v = samples(result)[0]
        errors.append(l2(v, reference, weights))
        differences.append(l2(v, original[seed - 1], weights))
        rates.append(result["stats"]["photons"] / result["stats"]["seconds"])
    print("| %s | %.1e | %s | %s | %s |" % (name, l2(own_reference, reference, weights),
          spread.cell(errors, lambda v: "%.2e" % v), spread.cell(differences, lambda v: "%.1e" % v),
          spread.cell([r / 1e6 for r in rates], lambda v: "%.2f" % v, "M")))
    smallest = min(smallest, median(errors))
ok, text = reference_check(load(os.path.join(work, "curved_room-reference.json")), smallest)
print("\nReference of the original (N = 1600): " + text + ".")
if not ok:
    sys.exit("the reference is not 10x more accurate than the errors it judges")
PY

#!/usr/bin/env bash
# Prints the method comparison table of docs/method.md: relative L2 error of B along the penumbra
# scene's receiver against its closed form, and solve seconds, for every basis, both position
# samplers and point / footprint / band rays, at equal photon counts; medians over seeds with their
# interquartile range.
# Needs build/flatland and python3. Usage: docs/figures/penumbra_table.sh [PHOTONS] [SEEDS]
set -euo pipefail
cd "$(dirname "$0")/../.."
flatland=${FLATLAND:-build/flatland}
# So that a change of the program's defaults does not change what this measures, every setting
# it does not vary is pinned to the paper's setting (16 elements per curve, lumped deposits, direct-light events, pseudo-random numbers).
pin=(--elements 16 --estimator lumped --discontinuities auto --sampler random --tolerance 1e-6 --transport shooting --gather none --control-variate none)
photons=${1:-400000}
seeds=${2:-5}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for basis in constant linear cubic hermite; do
  for sampling in uniform reconstructed; do
    for rays in point footprint band; do
      case $rays in
        point) extra=() ;;
        footprint) extra=(--ray-width 0.05 --ray-mode footprint --ray-profile tent) ;;
        band) extra=(--ray-width 0.05 --ray-mode band --band-rays 4 --ray-profile tent) ;;
      esac
      for seed in $(seq 1 "$seeds"); do
        "$flatland" solve "${pin[@]}" scenes2d/penumbra.json --basis "$basis" --sampling "$sampling" \
          --photons "$photons" --seed "$seed" --samples 600 --threads 1 --quiet "${extra[@]}" \
          --out "$work/$basis-$sampling-$rays-$seed.json"
      done
    done
  done
done
python3 - "$work" "$photons" "$seeds" <<'PY'
import json, math, os, sys
sys.path.insert(0, os.path.join("docs", "figures"))
import spread
work, photons, seeds = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
def exact(x, rho=0.5):
    sine = lambda px, py: (px - x) / math.hypot(px - x, py)
    a, b = sine(-0.5, 2.0), sine(0.5, 2.0)
    c, d = max(a, sine(-0.1, 1.0)), min(b, sine(0.7, 1.0))
    return rho * 0.5 * ((b - a) - (d - c if d > c else 0.0))
print(f"Relative L2 error of B on the receiver against its closed form, and solve seconds (one thread), each the "
      f"{spread.caption(seeds)}:\n")
print("| basis | positions | rays | rel. L2 error | seconds |")
print("|---|---|---|---|---|")
for basis in ("constant", "linear", "cubic", "hermite"):
    for sampling in ("uniform", "reconstructed"):
        for rays in ("point", "footprint", "band"):
            errors, seconds = [], []
            for seed in range(1, seeds + 1):
                r = json.load(open(f"{work}/{basis}-{sampling}-{rays}-{seed}.json"))
                c = next(c for c in r["curves"] if c["id"] == "receiver")
                e = sum((s["B"] - exact(s["x"])) ** 2 for s in c["samples"])
                n = sum(exact(s["x"]) ** 2 for s in c["samples"])
                errors.append(math.sqrt(e / n))
                seconds.append(r["stats"]["seconds"])
            print(f"| {basis} | {sampling} | {rays} | {spread.cell(errors, lambda v: '%.4f' % v)} "
                  f"| {spread.cell(seconds, lambda v: '%.3f' % v)} |")
PY

#!/usr/bin/env bash
# Experiment 2 of docs/experiments.md: the constant radiosity assumption syndrome. On
# scenes2d/syndrome.json, B along the ceiling (lit only by the floor's reflection) and along the
# floor, from the reference and from solves at equal photon counts with photon origins uniform in
# arc length and following the reconstruction, for constant and cubic storage. Writes
# docs/figures/experiments/syndrome.png and prints the table of errors (median over SEEDS seeds).
# Needs build/flatland, python3 and gnuplot. THREADS=N passes --threads N (default: 2).
# Usage: [THREADS=N] docs/figures/experiments/syndrome.sh [PHOTONS] [SEEDS]
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-build/flatland}
# So that a change of the program's defaults does not change what this measures, what the experiment does not vary is pinned to the defaults (Galerkin estimator, direct-light events, Sobol' points, point rays).
pin=(--estimator galerkin --discontinuities auto --sampler sobol --ray-width 0 --transport shooting --gather none --control-variate none)
photons=${1:-1e6}
seeds=${2:-5}
threads=(--threads "${THREADS:-2}")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene=scenes2d/syndrome.json
"$flatland" reference "$scene" --elements 1600 --samples 200 --quiet "${threads[@]}" --out "$work/reference.json"
for basis in constant cubic; do
  for sampling in uniform reconstructed; do
    for elements in 16 64; do
      for seed in $(seq 1 "$seeds"); do
        "$flatland" solve "${pin[@]}" "$scene" --basis "$basis" --sampling "$sampling" --elements "$elements" \
          --photons "$photons" --tolerance 1e-6 --seed "$seed" --samples 200 --quiet "${threads[@]}" \
          --out "$work/$basis-$sampling-$elements-$seed.json"
      done
    done
  done
done
python3 - "$work" "$seeds" "$photons" <<'PY'
import os, sys
sys.path.insert(0, os.path.join("docs", "figures", "experiments"))
from analysis import load, samples, l2, median, reference_check
work, seeds, photons = sys.argv[1], int(sys.argv[2]), sys.argv[3]
reference = load(os.path.join(work, "reference.json"))
print("| storage | elements | photon origins | rel. L2 error, ceiling | rel. L2 error, floor | rel. L2 error, scene | seconds |")
print("|---|---|---|---|---|---|---|")
smallest = {}
for basis in ("constant", "cubic"):
    for elements in (16, 64):
        for sampling in ("uniform", "reconstructed"):
            errors = {"ceiling": [], "floor": [], None: []}
            seconds = []
            for seed in range(1, seeds + 1):
                run = load(os.path.join(work, "%s-%s-%d-%d.json" % (basis, sampling, elements, seed)))
                seconds.append(run["stats"]["seconds"])
                for curve in errors:
                    v, w = samples(run, curve)
                    r, _ = samples(reference, curve)
                    errors[curve].append(l2(v, r, w))
            print("| %s | %d | %s | %.3f | %.3f | %.3f | %.3f |" % (
                basis, elements, sampling, median(errors["ceiling"]), median(errors["floor"]),
                median(errors[None]), median(seconds)))
            for curve in errors:
                smallest[curve] = min(smallest.get(curve, 1.0), median(errors[curve]))
checks = [reference_check(reference, smallest[curve], curve) for curve in ("ceiling", "floor", None)]
print()
print("Reference (N = 1600): " + "; ".join(text for _, text in checks) + ".")
if not all(ok for ok, _ in checks):
    sys.exit("the reference is not 10x more accurate than the errors it judges")
# The curves along the ceiling and the floor (seed 1, cubic, 16 elements), against x.
with open(os.path.join(work, "curves.dat"), "w") as f:
    for curve in ("ceiling", "floor"):
        ref = next(c for c in reference["curves"] if c["id"] == curve)
        runs = {s: next(c for c in load(os.path.join(work, "cubic-%s-16-1.json" % s))["curves"] if c["id"] == curve)
                for s in ("uniform", "reconstructed")}
        for i, sample in enumerate(ref["samples"]):
            f.write("%.6g %.6g %.6g %.6g\n" % (sample["x"], sample["B"], runs["uniform"]["samples"][i]["B"],
                                               runs["reconstructed"]["samples"][i]["B"]))
        f.write("\n\n")
PY
gnuplot <<GP
set terminal pngcairo size 1000,700
set output 'docs/figures/experiments/syndrome.png'
set multiplot layout 2,1 title "constant radiosity syndrome: B along the ceiling and the floor ($photons photons, cubic, 16 elements, seed 1)"
set xlabel 'x (m)'
set ylabel 'B on the ceiling (W/m)'
set key top right
set grid
plot '$work/curves.dat' index 0 using 1:2 with lines lw 3 lc rgb 'black' title 'reference', \
     '' index 0 using 1:3 with lines lw 2 lc rgb '#d62728' title 'uniform origins', \
     '' index 0 using 1:4 with lines lw 2 lc rgb '#1f77b4' title 'reconstructed origins (the paper)'
set ylabel 'B on the floor (W/m, log scale)'
set logscale y
plot '$work/curves.dat' index 1 using 1:2 with lines lw 3 lc rgb 'black' title 'reference', \
     '' index 1 using 1:3 with lines lw 2 lc rgb '#d62728' title 'uniform origins', \
     '' index 1 using 1:4 with lines lw 2 lc rgb '#1f77b4' title 'reconstructed origins (the paper)'
unset multiplot
GP

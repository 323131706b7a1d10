#!/usr/bin/env bash
# Experiment 4 of docs/experiments.md: photons needed for a fixed Monte Carlo error against the
# number of storage elements (Shirley's O(N) bound for equal-power photons). On the curved room,
# constant and cubic storage with N = 4 .. 1024 elements per curve, SEEDS seeds at PHOTONS photons:
# the noise of one run (its RMS distance from the mean of the seeds, relative L2) gives the photons
# that reach a relative L2 noise of 1 %: PHOTONS x (noise / 0.01)^2 (the noise falls as
# 1 / sqrt(photons), which the run at PHOTONS / 10 checks). The bias (the storage's own error)
# does not depend on the photons and is reported apart. Writes docs/figures/experiments/elements.png
# and prints the table. Needs build/flatland, python3, gnuplot.
# Usage: docs/figures/experiments/elements.sh [PHOTONS] [SEEDS]
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-build/flatland}
# So that a change of the program's defaults does not change what this measures, what the experiment does not vary is pinned to plain Monte Carlo as Shirley's bound assumes it (lumped deposits, pseudo-random numbers, point rays).
pin=(--estimator lumped --sampler random --sampling reconstructed --ray-width 0 --transport shooting --gather none --control-variate none --threads 2)
photons=${1:-1000000}
seeds=${2:-8}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene=scenes2d/curved_room.json
"$flatland" reference "$scene" --elements 1600 --samples 4096 --quiet \
  --out "$work/reference.json"
tenth=$((photons / 10))
for basis in constant cubic; do
  for n in 4 16 64 256 1024; do
    for p in "$photons" "$tenth"; do
      for seed in $(seq 1 "$seeds"); do
        "$flatland" solve "${pin[@]}" "$scene" --basis "$basis" --elements "$n" --discontinuities scene \
          --photons "$p" --tolerance 1e-6 --seed "$seed" --samples 4096 --quiet \
          --out "$work/$basis-$n-$p-$seed.json"
      done
    done
  done
done
python3 - "$work" "$seeds" "$photons" "$tenth" <<'PY'
import os, sys
sys.path.insert(0, os.path.join("docs", "figures", "experiments"))
from analysis import load, samples, bias_and_noise, reference_check
work, seeds, photons, tenth = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
reference_result = load(os.path.join(work, "reference.json"))
reference, weights = samples(reference_result)
resolved = []  # biases the seeds resolve: above the noise of their mean
target = 0.01
print("| storage | elements per curve | coefficients | noise at %s photons | noise at %s | ratio (sqrt 10 = 3.16) | photons for 1 %% noise | photons / coefficients | bias |" % (f"{photons:,}", f"{tenth:,}"))
print("|---|---|---|---|---|---|---|---|---|")
import math
fits = []
with open(os.path.join(work, "needed.dat"), "w") as data:
    for basis in ("constant", "cubic"):
        points = []
        for n in (4, 16, 64, 256, 1024):
            noise = {}
            bias = None
            coefficients = 0
            for p in (photons, tenth):
                runs = []
                for seed in range(1, seeds + 1):
                    result = load(os.path.join(work, "%s-%d-%d-%d.json" % (basis, n, p, seed)))
                    runs.append(samples(result)[0])
                    coefficients = sum(len(c.get("coefficients", [])) + len(c.get("coefficients_back", []))
                                       for c in result["curves"])
                b, s = bias_and_noise(runs, reference, weights)
                noise[p] = s
                if p == photons:
                    bias = b
            if bias > noise[photons] / seeds ** 0.5:
                resolved.append(bias)
            needed = photons * (noise[photons] / target) ** 2
            print("| %s | %d | %d | %.4f | %.4f | %.2f | %.3g | %.0f | %.4f |" % (
                basis, n, coefficients, noise[photons], noise[tenth], noise[tenth] / noise[photons],
                needed, needed / coefficients, bias))
            data.write("%d %d %.6g\n" % (n, coefficients, needed))
            points.append((math.log(coefficients), math.log(needed)))
        data.write("\n\n")
        # Least-squares slope of log(photons needed) against log(coefficients).
        mx = sum(x for x, _ in points) / len(points)
        my = sum(y for _, y in points) / len(points)
        slope = sum((x - mx) * (y - my) for x, y in points) / sum((x - mx) ** 2 for x, _ in points)
        fits.append((basis, slope, math.exp(my - mx)))
for basis, slope, _ in fits:
    print("\n%s: photons needed grow as coefficients^%.3f" % (basis, slope))
# Only the bias column is measured against the reference (the noise is each run's distance from
# the seeds' mean); it must be 10x below the smallest bias the seeds resolve.
ok, text = reference_check(reference_result, min(resolved), what="the smallest resolved bias")
print("\nReference (N = 1600): " + text + ".")
if not ok:
    sys.exit("the reference is not 10x more accurate than the errors it judges")
with open(os.path.join(work, "guide.gp"), "w") as f:
    f.write("a = %.9g\n" % fits[0][2])
PY
gnuplot <<GP
set terminal pngcairo size 900,600
set output 'docs/figures/experiments/elements.png'
set logscale xy
set xlabel 'storage coefficients in the scene'
set ylabel 'photons for a relative L2 noise of 1 %'
set title "curved room: photons needed against storage size (from $seeds seeds at $photons photons)"
set key top left
set grid
load '$work/guide.gp'
f(x) = a * x
plot '$work/needed.dat' index 0 using 2:3 with linespoints lw 2 pt 7 title 'constant', \
     '' index 1 using 2:3 with linespoints lw 2 pt 5 title 'cubic', \
     f(x) with lines dt 2 lc rgb 'gray40' title 'slope 1 (O(N))'
GP

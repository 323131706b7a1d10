#!/usr/bin/env bash
# Experiment 5 of docs/experiments.md: extended-ray width against bias and noise at fixed photon
# counts. On the penumbra scene (closed form: the reference reproduces it to round-off), cubic
# storage with 128 elements per curve, footprint and band rays (box profile) of widths 0 .. 0.4 m,
# SEEDS seeds at 1e5 and 1e6 photons. Bias: the relative L2 distance of the mean over seeds from
# the reference along the receiver; noise: one run's RMS distance from that mean. Writes
# docs/figures/experiments/width.png and prints the table. Needs build/flatland, python3, gnuplot.
# Usage: docs/figures/experiments/width.sh [SEEDS]
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-build/flatland}
# So that a change of the program's defaults does not change what this measures, what the experiment does not vary is pinned to the paper's method (cubic, lumped deposits, reconstructed origins, direct-light events, pseudo-random numbers: the noise ~ 1/sqrt(N W) is Monte Carlo's).
pin=(--basis cubic --estimator lumped --sampler random --sampling reconstructed --discontinuities auto --ray-profile box --transport shooting --gather none --control-variate none --threads 2)
seeds=${1:-16}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
scene=scenes2d/penumbra.json
widths="0 0.005 0.01 0.02 0.05 0.1 0.2 0.4"
"$flatland" reference "$scene" --elements 1600 --samples 600 --quiet \
  --out "$work/reference.json"
for mode in footprint band; do
  for w in $widths; do
    [ "$mode" = band ] && [ "$w" = 0 ] && continue
    for p in 100000 1000000; do
      for seed in $(seq 1 "$seeds"); do
        "$flatland" solve "${pin[@]}" "$scene" --elements 128 --ray-width "$w" --ray-mode "$mode" \
          --photons "$p" --tolerance 1e-6 --seed "$seed" --samples 600 --quiet \
          --out "$work/$mode-$w-$p-$seed.json"
      done
    done
  done
done
python3 - "$work" "$seeds" "$widths" <<'PY'
import os, sys
sys.path.insert(0, os.path.join("docs", "figures", "experiments"))
from analysis import load, samples, bias_and_noise, median, reference_check
work, seeds, widths = sys.argv[1], int(sys.argv[2]), sys.argv[3].split()
reference_result = load(os.path.join(work, "reference.json"))
reference, weights = samples(reference_result, "receiver")
smallest = 1.0
print("| rays | width (m) | photons | bias | noise | total (sqrt(bias^2 + noise^2)) | seconds |")
print("|---|---|---|---|---|---|---|")
with open(os.path.join(work, "width.dat"), "w") as data:
    for mode in ("footprint", "band"):
        for p in (100000, 1000000):
            for w in widths:
                if mode == "band" and w == "0":
                    continue
                runs, seconds = [], []
                for seed in range(1, seeds + 1):
                    result = load(os.path.join(work, "%s-%s-%d-%d.json" % (mode, w, p, seed)))
                    runs.append(samples(result, "receiver")[0])
                    seconds.append(result["stats"]["seconds"])
                bias, noise = bias_and_noise(runs, reference, weights)
                total = (bias ** 2 + noise ** 2) ** 0.5
                smallest = min(smallest, total)
                print("| %s | %s | %s | %.4f | %.4f | %.4f | %.3f |" % (
                    "point" if w == "0" else mode, w, f"{p:,}", bias, noise, total, median(seconds)))
                # Width 0 drawn at 0.002 so that it shows on the log axis.
                data.write("%s %.6g %.6g %.6g\n" % (w if w != "0" else "0.002", bias, noise, total))
            data.write("\n\n")
ok, text = reference_check(reference_result, smallest, "receiver", what="the smallest total error")
print("\nReference (N = 1600): " + text + ".")
if not ok:
    sys.exit("the reference is not 10x more accurate than the errors it judges")
PY
gnuplot <<GP
set terminal pngcairo size 1000,640
set output 'docs/figures/experiments/width.png'
set logscale xy
set xlabel 'ray width W (m); point rays drawn at 0.002'
set ylabel 'relative L2 along the receiver'
set title "penumbra: bias and noise of extended rays (cubic, 128 elements, $seeds seeds)"
set key outside right
set grid
plot '$work/width.dat' index 1 using 1:2 with linespoints lw 2 pt 7 lc rgb '#1f77b4' title 'bias, footprint (1e6)', \
     '' index 0 using 1:3 with linespoints lw 2 pt 6 dt 2 lc rgb '#1f77b4' title 'noise, footprint, 1e5', \
     '' index 1 using 1:3 with linespoints lw 2 pt 6 dt 2 lc rgb '#2ca02c' title 'noise, footprint, 1e6', \
     '' index 3 using 1:2 with linespoints lw 2 pt 5 lc rgb '#d62728' title 'bias, band (1e6)', \
     '' index 2 using 1:3 with linespoints lw 2 pt 4 dt 2 lc rgb '#d62728' title 'noise, band, 1e5', \
     '' index 3 using 1:3 with linespoints lw 2 pt 4 dt 2 lc rgb '#ff7f0e' title 'noise, band, 1e6'
GP

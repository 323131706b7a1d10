#!/usr/bin/env bash
# Regenerates docs/figures/penumbra.png: B along the penumbra scene's receiver for the constant,
# linear and cubic (automatic discontinuities) reconstructions at equal photon counts, against the
# closed form. Needs a built flatland (build/flatland), python3 and gnuplot (apt-get install
# gnuplot-nox). Usage: docs/figures/penumbra.sh [PHOTONS]
set -euo pipefail
cd "$(dirname "$0")/../.."
flatland=${FLATLAND:-build/flatland}
# So that a change of the program's defaults does not change what this measures, every setting
# it does not vary is pinned to the paper's setting (lumped deposits, reconstructed origins, direct-light events, pseudo-random numbers, point rays).
pin=(--estimator lumped --sampling reconstructed --discontinuities auto --sampler random --tolerance 1e-6 --ray-width 0 --transport shooting --gather none --control-variate none --threads 2)
photons=${1:-400000}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for basis in constant linear cubic; do
  "$flatland" solve "${pin[@]}" scenes2d/penumbra.json --basis "$basis" --elements 16 --photons "$photons" --seed 7 \
    --samples 600 --quiet --out "$work/$basis.json"
done
python3 - "$work" <<'PY'
import json, math, sys
work = sys.argv[1]
# Closed form: B(x) = rho E (1/2) * (visible measure of the emitter in sin(theta)), theta from the
# receiver's normal; emitter x in [-0.5, 0.5] at y = 2, occluder x in [-0.1, 0.7] at y = 1.
def exact(x, rho=0.5):
    sine = lambda px, py: (px - x) / math.hypot(px - x, py)
    a, b = sine(-0.5, 2.0), sine(0.5, 2.0)
    c, d = max(a, sine(-0.1, 1.0)), min(b, sine(0.7, 1.0))
    visible = (b - a) - (d - c if d > c else 0.0)
    return rho * 0.5 * visible
for basis in ("constant", "linear", "cubic"):
    result = json.load(open(f"{work}/{basis}.json"))
    curve = next(c for c in result["curves"] if c["id"] == "receiver")
    with open(f"{work}/{basis}.dat", "w") as out:
        for s in curve["samples"]:
            out.write(f'{s["x"]} {s["B"]} {exact(s["x"])}\n')
PY
gnuplot <<GP
set terminal pngcairo size 900,480 font ",11"
set output "docs/figures/penumbra.png"
set title "Penumbra scene: B along the receiver, $photons photons, 16 elements per curve"
set xlabel "x on the receiver (m)"
set ylabel "radiosity B (W/m)"
set xrange [-2:2.5]
set key top right
plot "$work/cubic.dat" using 1:3 with lines lw 3 lc rgb "black" title "closed form", \
     "$work/constant.dat" using 1:2 with lines lw 1.5 lc rgb "#d95f02" title "constant", \
     "$work/linear.dat" using 1:2 with lines lw 1.5 lc rgb "#7570b3" title "linear", \
     "$work/cubic.dat" using 1:2 with lines lw 2 lc rgb "#1b9e77" title "cubic, automatic C0 nodes"
GP
echo "wrote docs/figures/penumbra.png"

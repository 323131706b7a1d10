#!/usr/bin/env bash
# Experiment 6a of docs/experiments.md: stiff closed scenes. The elliptic enclosure (E = 1
# everywhere) with rho = 0.9, 0.99 and 0.999 (scenes2d/experiments/enclosure_rho*.json, closed form
# B = 1 / (1 - rho)), cubic storage, photon budgets 1e5 .. 1e7 and the default tolerance 1e-3 (the
# solve stops when the unshot power falls below 1e-3 of the emitted power, or when the budget is
# spent), SEEDS seeds. Prints rounds, photons, seconds, unshot power, the mean relative bias of B
# and its relative L2 error against the closed form (medians over seeds).
# Needs build/flatland and python3. Usage: docs/figures/experiments/stiff.sh [SEEDS] [TOLERANCE]
set -euo pipefail
cd "$(dirname "$0")/../../.."
flatland=${FLATLAND:-build/flatland}
# So that a change of the program's defaults does not change what this measures, every other setting is pinned to the defaults (cubic, Galerkin, auto mesh, Sobol' points).
pin=(--basis cubic --estimator galerkin --elements auto --sampling reconstructed --discontinuities auto --sampler sobol --ray-width 0 --transport shooting --gather none --control-variate none --threads 2)
seeds=${1:-5}
tolerance=${2:-1e-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for rho in 0.9 0.99 0.999; do
  for p in 100000 1000000 10000000; do
    for seed in $(seq 1 "$seeds"); do
      "$flatland" solve "${pin[@]}" "scenes2d/experiments/enclosure_rho$rho.json" --photons "$p" \
        --tolerance "$tolerance" --seed "$seed" --samples 200 --quiet --out "$work/$rho-$p-$seed.json"
    done
  done
done
python3 - "$work" "$seeds" <<'PY'
import math, os, sys
sys.path.insert(0, os.path.join("docs", "figures", "experiments"))
from analysis import load, samples, median
work, seeds = sys.argv[1], int(sys.argv[2])
print("| rho | budget | stop | rounds | photons | seconds | unshot / emitted | mean B / exact - 1 | rel. L2 error |")
print("|---|---|---|---|---|---|---|---|---|")
for rho in ("0.9", "0.99", "0.999"):
    exact = 1.0 / (1.0 - float(rho))
    for p in (100000, 1000000, 10000000):
        rows = []
        for seed in range(1, seeds + 1):
            result = load(os.path.join(work, "%s-%d-%d.json" % (rho, p, seed)))
            values, weights = samples(result)
            total = sum(weights)
            mean = sum(v * w for v, w in zip(values, weights)) / total
            error = math.sqrt(sum(w * (v - exact) ** 2 for v, w in zip(values, weights)) / (total * exact ** 2))
            stats = result["stats"]
            rows.append((stats["rounds"], stats["photons"], stats["seconds"],
                         stats["unshot_power"] / stats["emitted_power"], mean / exact - 1.0, error,
                         stats["stop_reason"]))
        stops = sorted(set(r[6] for r in rows))
        print("| %s | %s | %s | %d | %s | %.3f | %.2e | %+.2e | %.2e |" % (
            rho, f"{p:,}", " / ".join(stops), median([r[0] for r in rows]), f"{int(median([r[1] for r in rows])):,}",
            median([r[2] for r in rows]), median([r[3] for r in rows]), median([r[4] for r in rows]),
            median([r[5] for r in rows])))
PY

#!/usr/bin/env bash
# Secondary-source events (docs/method.md, Direct-light events): `--discontinuities auto` against
# `secondary` on the four rooms, with the default storage (Galerkin, auto elements) and with the
# paper's (lumped deposits on 16 fixed elements per curve), at 1e6 and 1e7 photons, SEEDS (3) seeds,
# against a reference of N = 800. Prints the median relative L2 error of B - E per method and budget.
# Needs build/flatland (and gnuplot for converge's plots, written to a temporary directory).
# Usage: [SEEDS=N] docs/figures/experiments/secondary.sh
set -euo pipefail
cd "$(dirname "$0")/../../.."
seeds=${SEEDS:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for scene in curved_room room_reflector default syndrome; do
  build/flatland reference "scenes2d/$scene.json" --elements 800 --samples 200 --quiet --out "$work/$scene-ref.json"
  build/flatland converge "scenes2d/$scene.json" --reference "$work/$scene-ref.json" \
    --methods "cubic,cubic+discontinuities=secondary,cubic+elements=16+estimator=lumped,cubic+elements=16+estimator=lumped+discontinuities=secondary" \
    --budgets 1e6,1e7 --seeds "$seeds" --samples 200 --out "$work/$scene" >/dev/null 2>&1
done
python3 - "$work" <<'PY'
import collections, csv, statistics, sys
work = sys.argv[1]
print("| scene | storage | photons | auto | secondary | auto / secondary |")
print("|---|---|---|---|---|---|")
for scene in ["curved_room", "room_reflector", "default", "syndrome"]:
    errors = collections.defaultdict(list)
    for row in csv.DictReader(open(f"{work}/{scene}/convergence.csv")):
        secondary = "discontinuities=secondary" in row["method"]
        storage = "16 lumped" if "elements=16" in row["method"] else "auto, Galerkin"
        errors[(storage, "%.0e" % float(row["photons"]), secondary)].append(float(row["rel_l2"]))
    for storage in ["auto, Galerkin", "16 lumped"]:
        for photons in ["1e+06", "1e+07"]:
            a = statistics.median(errors[(storage, photons, False)])
            s = statistics.median(errors[(storage, photons, True)])
            print(f"| {scene} | {storage} | {photons} | {a:.4f} | {s:.4f} | {a / s:.2f} |")
PY

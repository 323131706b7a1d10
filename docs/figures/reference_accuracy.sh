#!/usr/bin/env bash
# Estimates the reference solver's own error on every example scene: references with elements
# no longer than scene size / N for N = 100, 200, 400, 800; the difference of two successive ones,
# divided by 3 (second-order convergence), estimates the error of the finer one.
# Needs build/flatland. Usage: docs/figures/reference_accuracy.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
printf "| scene | N | elements | seconds | estimated rel. L2 error |\n|---|---|---|---|---|\n"
for scene in scenes2d/*.json; do
  name=$(basename "$scene" .json)
  previous=""
  for n in 100 200 400 800; do
    out="$work/$name-$n.json"
    build/flatland reference "$scene" --elements "$n" --samples 200 --quiet --out "$out"
    elements=$(python3 -c "import json; d=json.load(open('$out')); print(d['stats']['elements'], '%.2f' % d['stats']['seconds'])")
    if [ -n "$previous" ]; then
      l2=$(build/flatland compare "$previous" "$out" | awk '/\(scene\)/ {print $3}')
      estimate=$(python3 -c "print('%.2e' % (float('$l2') / 3))")
    else
      estimate="-"
    fi
    printf "| %s | %s | %s | %s | %s |\n" "$name" "$n" "${elements% *}" "${elements#* }" "$estimate"
    previous=$out
  done
done

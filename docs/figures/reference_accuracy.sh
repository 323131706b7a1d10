#!/usr/bin/env bash
# The reference solver's own error (docs/reference.md).
#  1. Every example scene at elements no longer than scene size / N, N = 100, 200, 400, 800:
#     `flatland reference` solves again at 2h and 4h and estimates the error of the solve at h as
#     |R_2h - R_h| / (2^p - 1), p the order observed from the three (stats.estimated_error,
#     stats.observed_order).
#  2. The closed-form scenes (penumbra, round occluder, ring): that estimate against the true
#     error, from the test that holds the closed forms (tests/reference/reference_test.cpp,
#     Reference.DISABLED_EstimatedAgainstTrueErrorTable).
# Needs the program FLATLAND (default BUILD/flatland) and BUILD/reference_test (BUILD defaults to
# build): docs/reproduce.sh sets FLATLAND, so that every step measures the same program.
# Usage: docs/figures/reference_accuracy.sh [BUILD [TABLES]]: with TABLES (a directory, docs/reproduce.sh
# gives docs/tables) the tables go to TABLES/reference-accuracy-2.md (1.) and -1.md (2.), else to stdout.
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build}
flatland=${FLATLAND:-$build/flatland}
tables=${2:-}
[ -z "$tables" ] || exec > "$tables/reference-accuracy-2.md.partial"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
printf "| scene | N | elements | seconds | estimated rel. L2 error | observed order |\n|---|---|---|---|---|---|\n"
for scene in scenes2d/*.json; do
  name=$(basename "$scene" .json)
  for n in 100 200 400 800; do
    out="$work/$name-$n.json"
    # Scenes with glass, detectors, curved or rough mirrors or emitters other than diffuse ones
    # are refused by the reference (docs/reference.md): one row says so, with its reason.
    if ! "$flatland" reference "$scene" --elements "$n" --quiet --out "$out" 2> "$work/refused"; then
      grep -q 'the reference solver' "$work/refused" || { cat "$work/refused" >&2; exit 1; }
      reason=$(sed -n 's/.*\(the reference solver [^;]*\).*/\1/p' "$work/refused")
      echo "| $name | - | - | - | not solved: $reason | - |"
      break
    fi
    python3 - "$out" "$name" "$n" <<'EOF'
import json, sys
stats = json.load(open(sys.argv[1]))["stats"]
order = stats.get("observed_order")
note = stats.get("estimate_note", "")
order_text = "-" if order is None else "%.2f" % order
if order is None and "round-off" in note:
    order_text = "- (round-off)"
print("| %s | %s | %d | %.2f | %.2e | %s |" % (sys.argv[2], sys.argv[3], stats["elements"], stats["seconds"],
                                               stats["estimated_error"]["l2"], order_text))
EOF
  done
done
echo
[ -z "$tables" ] || exec > "$tables/reference-accuracy-1.md.partial"
"$build/reference_test" --gtest_also_run_disabled_tests \
  --gtest_filter=Reference.DISABLED_EstimatedAgainstTrueErrorTable | grep '^|'
# Both tables are complete: they replace the committed ones (a failed run leaves those alone).
if [ -n "$tables" ]; then
  mv "$tables/reference-accuracy-2.md.partial" "$tables/reference-accuracy-2.md"
  mv "$tables/reference-accuracy-1.md.partial" "$tables/reference-accuracy-1.md"
fi

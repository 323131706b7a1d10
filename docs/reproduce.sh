#!/usr/bin/env bash
# Regenerates every measured table and figure of README.md and docs/ at the current commit.
#
#   docs/reproduce.sh                 everything (about 30 minutes on 2 cores)
#   docs/reproduce.sh --quick         a representative subset (under 10 minutes), compared with the
#                                     committed tables; exit status 1 when they disagree
#   docs/reproduce.sh --list          the steps, their scripts and what they write
#   docs/reproduce.sh STEP...         only these steps (then the tables are pasted as usual)
#   FLATLAND=PATH docs/reproduce.sh   another executable (default build/flatland)
#
# Each step runs one experiment's script with every solver setting pinned in the script itself
# (basis, estimator, storage, origins, discontinuities, sampler, rays, photons, seeds, threads,
# reference resolution), so a change of the program's defaults does not change what it measures.
# A step writes its tables to docs/tables/NAME.md, each headed by the commit and command that made
# it and the step's run time, and its figures next to its script; then docs/figures/paste_tables.py
# copies every table into the documents between the markers <!-- table NAME --> and
# <!-- /table NAME -->, so a number is typed nowhere. The log of each step is kept in
# build/reproduce/STEP.log. Needs the program and the tests built (cmake --build build: the
# reference step runs build/reference_test), python3, gnuplot and xvfb-run (the viewer's pictures).
# The web page's pictures are taken by its tests (tests/web, docs/web.md), not here.
set -euo pipefail
cd "$(dirname "$0")/.."
export FLATLAND=${FLATLAND:-build/flatland}
export THREADS=2
tables=docs/tables
logs=build/reproduce
mkdir -p "$tables" "$logs"

# name | what it measures | the command (run from the repository's top) | tables it writes
STEPS=(
  "time-to-accuracy|error against solve time of every storage, with the defaults and the paper's settings, and of random walks, on five scenes|python3 docs/figures/time_to_accuracy/run.py|time-to-accuracy time-to-accuracy-errors time-to-accuracy-findings walks readme-answer"
  "ingredients|what each ingredient buys, one setting at a time from classic to the defaults, at 1e6 photons|python3 docs/figures/time_to_accuracy/ingredients.py|ingredients"
  "syndrome|the constant radiosity assumption syndrome|docs/figures/experiments/syndrome.sh 1e6 5|>syndrome"
  "storage-cost|run time against the size of the storage mesh|docs/figures/experiments/storage_cost.sh 2e6 3|>storage-cost"
  "elements|photons needed for a fixed error against the number of elements|docs/figures/experiments/elements.sh|>elements"
  "width|extended-ray width: bias and noise|docs/figures/experiments/width.sh|>width"
  "stiff|reflectivity near 1 in a closed enclosure|python3 docs/figures/experiments/make_scenes.py >/dev/null && docs/figures/experiments/stiff.sh|>stiff"
  "scale|tiny and huge scales, far from the origin|python3 docs/figures/experiments/make_scenes.py >/dev/null && docs/figures/experiments/scale.sh|>scale"
  "secondary|direct-light events of secondary sources|SEEDS=3 docs/figures/experiments/secondary.sh|>secondary"
  "penumbra-methods|every basis, origin sampling and ray kind on the penumbra scene against its closed form|docs/figures/penumbra_table.sh 400000 5 && docs/figures/penumbra.sh 400000 >/dev/null|>penumbra-methods"
  "estimators|lumped, Galerkin and local estimators on four scenes|WORK=\$(mktemp -d) ELEMENTS='16 64' BUDGETS='1e5 1e6 1e7' SEEDS=3 docs/figures/estimators/estimators.sh > /dev/null && cp docs/figures/estimators/compact.md docs/tables/estimators.md|estimators"
  "estimator-storage|each estimator on 16 fixed elements and on storage that follows the photons|python3 docs/figures/estimators/storage.py|>estimator-storage"
  "seam|the closing point of a closed curve against its Fourier closed form|python3 docs/figures/seam/ring_seam.py build 1e7 3 cubic,linear|>seam"
  "reference-accuracy|the reference solver's own error|docs/figures/reference_accuracy.sh build docs/tables|reference-accuracy-1 reference-accuracy-2"
  "coverage|coverage and sharpness of the estimated error|python3 bench/error_coverage.py --out build/reproduce/coverage --seeds 40|>coverage"
  "target-error|what --target-error spends and delivers|python3 bench/target_error.py --out build/reproduce/target --seeds 20 --scenes 'penumbra,round occluder,furnace rho 0.9'|>target-error"
  "estimated-error-figure|the estimated error against the true error, by photons|python3 bench/estimated_error_figure.py --out docs/figures/estimated_error|-"
  "specular|mirrors and glass against closed forms|python3 bench/specular_closed_forms.py --out build/reproduce/specular --photons 1e6 --seeds 5 && docs/figures/specular/make_pictures.sh >/dev/null|>specular"
  "pictures|gallery of the test scenes, the error along a curve, the discontinuity mesh, an extended ray|docs/figures/pictures/make.sh && python3 docs/figures/pictures/to_tables.py|pictures-gallery pictures-curves"
  "geometry|pictures of contacts and direct-light events|docs/figures/geometry/geometry.sh build|-"
  "viewer|the viewer's pictures in README.md and docs/viewer.md, taken by the viewer under a virtual X server|docs/figures/viewer.sh|-"
)
QUICK=(time-to-accuracy-quick syndrome stiff specular-quick)
QUICK_STEPS=(
  "time-to-accuracy-quick|two scenes, four methods, 1e4 to 1e6 photons, against the committed runs|python3 docs/figures/time_to_accuracy/run.py --quick|"
  "specular-quick|mirrors and glass against closed forms (the full step without its pictures)|python3 bench/specular_closed_forms.py --out build/reproduce/specular-quick --photons 1e6 --seeds 5|>specular"
)

field() { local IFS='|'; set -f; local parts=($1); set +f; echo "${parts[$2]:-}"; }

list() {
  for s in "${STEPS[@]}" "${QUICK_STEPS[@]}"; do
    printf '%-24s %s\n%-24s   %s\n%-24s   tables: %s\n' "$(field "$s" 0)" "$(field "$s" 1)" "" "$(field "$s" 2)" "" \
      "$(field "$s" 3 | tr -d '>')"
  done
}

commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
# Only what can change a number counts as a change (not the documents the tables are pasted into).
if [ -n "$(git status --porcelain --untracked-files=no -- src CMakeLists.txt bench scenes2d '*.py' '*.sh' 2>/dev/null)" ]; then
  commit="$commit (with uncommitted changes)"
fi
machine="$(nproc) cores, $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1)"

# Runs one step. A table spec ">NAME" means the command's standard output is the table (kept only
# when the step succeeds); a plain NAME means the script writes docs/tables/NAME.md itself, at its
# end. With COMPARE=1 the tables go to a
# scratch directory and are compared with the committed ones (docs/figures/compare_tables.py).
run_step() {
  local spec=$1 name cmd tabs start secs status=0
  name=$(field "$spec" 0); cmd=$(field "$spec" 2); tabs=$(field "$spec" 3)
  local out=$tables
  [ "${COMPARE:-0}" = 1 ] && out=$(mktemp -d)
  printf '%s: %s ... ' "$name" "$(field "$spec" 1)"
  start=$(date +%s)
  case $tabs in
    ">"*) bash -c "$cmd" > "$logs/$name.out" 2> "$logs/$name.log" || status=$?
          [ "$status" != 0 ] || mv "$logs/$name.out" "$out/${tabs#>}.md" ;;
    *) bash -c "$cmd" > "$logs/$name.log" 2>&1 || status=$? ;;
  esac
  secs=$(( $(date +%s) - start ))
  if [ "$status" != 0 ]; then
    echo "FAILED (exit $status) after $secs s; its log: $logs/$name.log"; tail -5 "$logs/$name.log" | sed 's/^/    /'
    return 1
  fi
  echo "$secs s"
  # A step that compares by itself (no table) says its verdict on its log's last line.
  [ -n "$tabs" ] || tail -1 "$logs/$name.log" | sed 's/^/  /'
  for t in ${tabs#>}; do
    [ "$t" = - ] && continue
    local f="$out/$t.md"
    [ -f "$f" ] || { echo "  $name wrote no $f"; return 1; }
    { printf '*Made by `docs/reproduce.sh %s` (`%s`) at commit %s in %d s on %s; reproduction tolerance and settings: docs/experiments.md.*\n\n' \
        "$name" "$cmd" "$commit" "$secs" "$machine"; cat "$f"; } > "$f.tmp" && mv "$f.tmp" "$f"
    if [ "${COMPARE:-0}" = 1 ]; then
      python3 docs/figures/compare_tables.py "$tables/$t.md" "$f" || return 1
    fi
  done
  echo "$name $secs" >> "$logs/times.txt"
}

quick=0
only=()
for a in "$@"; do
  case $a in
    --quick) quick=1 ;;
    --list) list; exit 0 ;;
    -h|--help) sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "docs/reproduce.sh: unknown option $a (see --help)" >&2; exit 2 ;;
    *) only+=("$a") ;;
  esac
done
[ -x "$FLATLAND" ] || { echo "docs/reproduce.sh: no executable $FLATLAND: build it first (cmake -S . -B build && cmake --build build -j 2) or set FLATLAND" >&2; exit 2; }
command -v gnuplot >/dev/null || { echo "docs/reproduce.sh: gnuplot is missing: apt-get install gnuplot-nox" >&2; exit 2; }
command -v xvfb-run >/dev/null || { echo "docs/reproduce.sh: xvfb-run is missing: apt-get install xvfb xauth (or .ci/setup)" >&2; exit 2; }

t0=$(date +%s)
: > "$logs/times.txt"
failed=0
if [ "$quick" = 1 ]; then
  echo "quick reproduction at commit $commit ($FLATLAND), against the committed tables:"
  for s in "${STEPS[@]}" "${QUICK_STEPS[@]}"; do
    name=$(field "$s" 0)
    case " ${QUICK[*]} " in *" $name "*) COMPARE=1 run_step "$s" || failed=1 ;; esac
  done
else
  for name in "${only[@]}"; do
    found=0
    for s in "${STEPS[@]}"; do [ "$(field "$s" 0)" = "$name" ] && found=1; done
    [ "$found" = 1 ] || { echo "docs/reproduce.sh: no step '$name' (docs/reproduce.sh --list)" >&2; exit 2; }
  done
  echo "reproducing at commit $commit ($FLATLAND) on $machine:"
  for s in "${STEPS[@]}"; do
    name=$(field "$s" 0)
    if [ "${#only[@]}" -gt 0 ] && ! printf '%s\n' "${only[@]}" | grep -qx "$name"; then continue; fi
    run_step "$s" || failed=1
  done
  python3 docs/figures/paste_tables.py
fi
total=$(( $(date +%s) - t0 ))
printf 'took %d min %d s' $(( total / 60 )) $(( total % 60 ))
if [ "$failed" = 1 ]; then echo "; SOME STEPS FAILED OR DISAGREE (above)"; exit 1; fi
echo "; every step done"

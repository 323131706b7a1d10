#!/usr/bin/env bash
# Regenerates every measured table and figure of README.md and docs/ at the current commit.
#
#   docs/reproduce.sh                 everything (about 55 minutes on 2 cores)
#   docs/reproduce.sh --quick         a representative subset (under 10 minutes), compared with the
#                                     committed tables, and the check that README.md and docs/*.md
#                                     show docs/tables (docs/figures/paste_tables.py --check); exit
#                                     status 1 when they disagree
#   docs/reproduce.sh --quick STEP... only these steps of the quick subset, compared, and the check
#   docs/reproduce.sh --list          the steps, their scripts and what they write
#   docs/reproduce.sh STEP...         only these steps (then the tables are pasted as usual); a step
#                                     of the quick subset only (NAME-quick) compares and writes nothing
#   docs/reproduce.sh --dry-run ...   checks the arguments and says what would run; runs nothing
#   FLATLAND=PATH docs/reproduce.sh   another executable (default build/flatland; a relative PATH
#                                     starts at the repository's top)
#
# Bad arguments (an unknown option or step, a step --quick does not run, a FLATLAND that is not an
# executable file, a missing tool) stop it with exit status 2 and a one-line message, before it
# creates, empties or writes any file.
#
# Each step runs one experiment's script with every solver setting pinned in the script itself
# (basis, estimator, storage, origins, discontinuities, sampler, rays, photons, seeds, threads,
# reference resolution), so a change of the program's defaults does not change what it measures.
# A step writes its tables to docs/tables/NAME.md, each headed by the commit and command that made
# it and the step's run time, and its figures next to its script; then docs/figures/paste_tables.py
# copies every table into the documents between the markers <!-- table NAME --> and
# <!-- /table NAME -->, so a number is typed nowhere. Every step takes the program from FLATLAND.
# The log of each step is kept in build/reproduce/STEP.log. Needs the program and the tests built
# (cmake --build build: the reference step runs build/reference_test), python3, gnuplot and, for
# the viewer step, xvfb-run. The web page's pictures are taken by its tests (tests/web,
# docs/web.md), not here.
set -euo pipefail
cd "$(dirname "$0")/.."
export FLATLAND=${FLATLAND:-build/flatland}
export THREADS=2
tables=docs/tables
logs=build/reproduce

# name | what it measures | the command (run from the repository's top) | tables it writes
STEPS=(
  "time-to-accuracy|error against solve time of every storage, with the defaults and the paper's settings, and of random walks, on five scenes|python3 docs/figures/time_to_accuracy/run.py|time-to-accuracy time-to-accuracy-errors time-to-accuracy-findings walks readme-answer"
  "family|the Monte Carlo radiosity family side by side: shooting, averaged Jacobi iterations, walks (each score) and the final gather against the deterministic reference, on eight scenes|python3 docs/figures/family/run.py|family family-findings"
  "control-variates|control variates for shooting predicted in the reference's discrete model before they are built: a constant and a coarse reference's answer, on five rooms and a furnace|build/flatland_control_variates scenes2d/interreflection/office.json scenes2d/interreflection/window_room.json scenes2d/curved_room.json scenes2d/default.json scenes2d/row_of_rooms.json scenes2d/experiments/enclosure_rho0.9.json --coarse 25,50|>control-variates"
  "importance|importance toward a region of interest: the region's error, the rest's and the time, with and without, on five scenes|python3 docs/figures/importance/run.py|importance"
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
  "geometry|pictures of contacts and direct-light events|docs/figures/geometry/geometry.sh|-"
  "viewer|the viewer's pictures in README.md and docs/viewer.md, taken by the viewer under a virtual X server|docs/figures/viewer.sh|-"
)
QUICK=(time-to-accuracy-quick syndrome stiff specular-quick)
# Steps of the quick subset only: they compare with the committed tables wherever they are named
# (with or without --quick) and write none.
QUICK_STEPS=(
  "time-to-accuracy-quick|two scenes, four methods, 1e4 to 1e6 photons, against the committed runs and tables|python3 docs/figures/time_to_accuracy/run.py --quick|"
  "specular-quick|mirrors and glass against closed forms (the full step without its pictures)|python3 bench/specular_closed_forms.py --out build/reproduce/specular-quick --photons 1e6 --seeds 5|>specular"
)

field() { local IFS='|'; set -f; local parts=($1); set +f; echo "${parts[$2]:-}"; }
# The spec of a step by its name (exit status 1 when there is none).
spec_of() { local s; for s in "${STEPS[@]}" "${QUICK_STEPS[@]}"; do [ "$(field "$s" 0)" = "$1" ] && { echo "$s"; return 0; }; done; return 1; }
is_quick_only() { local s; for s in "${QUICK_STEPS[@]}"; do [ "$(field "$s" 0)" = "$1" ] && return 0; done; return 1; }
in_quick() { case " ${QUICK[*]} " in *" $1 "*) return 0 ;; esac; return 1; }
named() { local n; for n in "${only[@]}"; do [ "$n" = "$1" ] && return 0; done; return 1; }
# A bad argument or a missing tool: one line on stderr, exit status 2, nothing written yet.
refuse() { echo "docs/reproduce.sh: $*" >&2; exit 2; }

list() {
  local s name
  for s in "${STEPS[@]}" "${QUICK_STEPS[@]}"; do
    name=$(field "$s" 0)
    printf '%-24s %s\n%-24s   %s\n' "$name" "$(field "$s" 1)" "" "$(field "$s" 2)"
    if is_quick_only "$name" && [ -z "$(field "$s" 3)" ]; then
      printf '%-24s   compares by itself; writes nothing (run by --quick)\n' ""
    elif is_quick_only "$name"; then
      printf '%-24s   compares with the committed tables: %s; writes nothing (run by --quick)\n' "" "$(field "$s" 3 | tr -d '>')"
    else
      printf '%-24s   tables: %s%s\n' "" "$(field "$s" 3 | tr -d '>')" "$(in_quick "$name" && echo ' (compared under --quick)')"
    fi
  done
}

# Every argument is checked here, before anything is created, emptied or written.
quick=0 dry=0 want_list=0 want_help=0
only=()
for a in "$@"; do
  case $a in
    --quick) quick=1 ;;
    --list) want_list=1 ;;
    --dry-run) dry=1 ;;
    -h|--help) want_help=1 ;;
    -*) refuse "unknown option '$a': the options are --quick, --list, --dry-run and --help" ;;
    *) only+=("$a") ;;
  esac
done
for name in "${only[@]}"; do
  spec_of "$name" >/dev/null || refuse "no step '$name': docs/reproduce.sh --list names the steps"
  if [ "$quick" = 1 ] && ! in_quick "$name"; then
    refuse "--quick runs only its own steps (${QUICK[*]}), not '$name': drop --quick to run '$name'"
  fi
done
if [ "$want_help" = 1 ]; then
  awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"
  exit 0
fi
[ "$want_list" = 0 ] || { list; exit 0; }

# The steps to run, in the order of the lists, and whether each compares or writes: under --quick
# every step compares; without it a step of the quick subset only compares and every other writes.
run=() compare=()
for s in "${STEPS[@]}" "${QUICK_STEPS[@]}"; do
  name=$(field "$s" 0)
  if [ "${#only[@]}" -gt 0 ]; then
    named "$name" || continue
  elif [ "$quick" = 1 ]; then
    in_quick "$name" || continue
  else
    is_quick_only "$name" && continue
  fi
  run+=("$s")
  if [ "$quick" = 1 ] || is_quick_only "$name"; then compare+=(1); else compare+=(0); fi
done
writes=0
for c in "${compare[@]}"; do [ "$c" = 1 ] || writes=1; done

[ -e "$FLATLAND" ] || refuse "FLATLAND=$FLATLAND does not exist: build it (cmake -S . -B build && cmake --build build -j 2) or set FLATLAND to the program"
[ -f "$FLATLAND" ] || refuse "FLATLAND=$FLATLAND is not a file: set FLATLAND to the program (such as build/flatland)"
[ -x "$FLATLAND" ] || refuse "FLATLAND=$FLATLAND is not executable: set FLATLAND to the program (such as build/flatland)"
command -v python3 >/dev/null || refuse "python3 is missing: apt-get install python3"
command -v gnuplot >/dev/null || refuse "gnuplot is missing: apt-get install gnuplot-nox"
for s in "${run[@]}"; do
  [ "$(field "$s" 0)" != viewer ] || command -v xvfb-run >/dev/null ||
    refuse "xvfb-run is missing (the viewer step needs it): apt-get install xvfb xauth (or .ci/setup)"
done

commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
# Only what can change a number counts as a change (not the documents the tables are pasted into).
if [ -n "$(git status --porcelain --untracked-files=no -- src CMakeLists.txt bench scenes2d '*.py' '*.sh' 2>/dev/null)" ]; then
  commit="$commit (with uncommitted changes)"
fi
machine="$(nproc) cores, $(sed -n 's/^model name\s*: //p' /proc/cpuinfo | head -1)"
# The compiler and flags the program was built with (its build directory's CMake cache), and the OS.
cache="$(dirname "$FLATLAND")/CMakeCache.txt"
if [ -f "$cache" ]; then
  cxx=$(sed -n 's/^CMAKE_CXX_COMPILER:FILEPATH=//p' "$cache")
  type=$(sed -n 's/^CMAKE_BUILD_TYPE:STRING=//p' "$cache")
  flags=$(sed -n "s/^CMAKE_CXX_FLAGS_$(echo "${type:-none}" | tr '[:lower:]' '[:upper:]'):STRING=//p" "$cache")
  machine="$machine, $("${cxx:-c++}" --version 2>/dev/null | head -1) ${type:-no build type} ($flags)"
fi
machine="$machine, $(sed -n 's/^PRETTY_NAME="\(.*\)"/\1/p' /etc/os-release 2>/dev/null | head -1)"

if [ "$dry" = 1 ]; then
  echo "would run at commit $commit ($FLATLAND):"
  for i in "${!run[@]}"; do
    s=${run[$i]}
    printf '  %-24s %s\n' "$(field "$s" 0)" "$([ "${compare[$i]}" = 1 ] && echo 'compared with the committed tables' || echo 'writes its tables and figures')"
  done
  if [ "$writes" = 1 ]; then echo "  then docs/figures/paste_tables.py"; else echo "  then docs/figures/paste_tables.py --check"; fi
  exit 0
fi
mkdir -p "$tables" "$logs"

# Runs one step. A table spec ">NAME" means the command's standard output is the table (kept only
# when the step succeeds); a plain NAME means the script writes docs/tables/NAME.md itself, at its
# end. With COMPARE=1 the tables go to build/reproduce/STEP.tables/ (kept to look at) and are
# compared with the committed ones (docs/figures/compare_tables.py, which prints every row it
# compared and how it agreed).
run_step() {
  local spec=$1 name cmd tabs start secs status=0
  name=$(field "$spec" 0); cmd=$(field "$spec" 2); tabs=$(field "$spec" 3)
  local out=$tables
  if [ "${COMPARE:-0}" = 1 ]; then out=$logs/$name.tables; rm -rf "$out"; mkdir -p "$out"; fi
  printf '%s: %s ... ' "$name" "$(field "$spec" 1)"
  start=$(date +%s)
  case $tabs in
    ">"*) bash -c "$cmd" > "$logs/$name.out" 2> "$logs/$name.log" || status=$?
          [ "$status" != 0 ] || mv "$logs/$name.out" "$out/${tabs#>}.md" ;;
    *) bash -c "$cmd" > "$logs/$name.log" 2>&1 || status=$? ;;
  esac
  secs=$(( $(date +%s) - start ))
  if [ "$status" != 0 ]; then
    echo "FAILED (exit $status) after $secs s; its log: $logs/$name.log"
    # A step that compares by itself (no table) says what disagrees in its log: all of it is shown.
    if [ -z "$tabs" ]; then sed 's/^/  /' "$logs/$name.log"; else tail -5 "$logs/$name.log" | sed 's/^/    /'; fi
    return 1
  fi
  echo "$secs s"
  # A step that compares by itself (no table) prints what it compared and its verdict, last.
  [ -n "$tabs" ] || sed 's/^/  /' "$logs/$name.log"
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

t0=$(date +%s)
: > "$logs/times.txt"
failed=0
if [ "$writes" = 1 ]; then
  echo "reproducing at commit $commit ($FLATLAND) on $machine:"
else
  echo "quick reproduction at commit $commit ($FLATLAND), against the committed tables:"
fi
for i in "${!run[@]}"; do
  COMPARE=${compare[$i]} run_step "${run[$i]}" || failed=1
done
if [ "$writes" = 1 ]; then
  python3 docs/figures/paste_tables.py || failed=1
else
  # The documents must show the committed tables: a number edited in a document alone differs.
  echo "the tables pasted into README.md and docs/*.md, against docs/tables:"
  python3 docs/figures/paste_tables.py --check | sed 's/^/  /' || failed=1
fi
total=$(( $(date +%s) - t0 ))
printf 'took %d min %d s' $(( total / 60 )) $(( total % 60 ))
if [ "$failed" = 1 ]; then echo "; SOME STEPS FAILED OR DISAGREE (above)"; exit 1; fi
echo "; every step done"

#!/usr/bin/env bash
# docs/reproduce.sh's own argument handling. Every bad invocation (an unknown step or option, --quick
# with a step it does not run, a FLATLAND that is a directory, missing or not executable) must exit
# 2 with a one-line message on stderr that names the bad argument, print nothing on stdout, and
# create, empty or write no file: build/reproduce/ (times.txt and the logs), docs/tables/, README.md
# and docs/*.md are checksummed before and after each one. Each runs twice: in the repository, and
# in a scratch copy of reproduce.sh whose build/reproduce/times.txt holds a line (an emptied
# times.txt shows there even where the repository has none). And every step --list names must run:
# docs/reproduce.sh --dry-run accepts it (with --quick too where --list says --quick runs it) and
# the scripts its command names exist. No step runs: the refused invocations stop before, and
# --dry-run only says what would run; a stand-in program and stand-in gnuplot and xvfb-run (never
# run) make the test need no build and no tools.
#
# Usage: tests/reproduce_args_test.sh [SOURCE_DIR]   (default: the repository holding this script)
# Prints one line per check and "N passed, M failed"; exit status 1 when a check fails.
set -uo pipefail
root=$(cd "${1:-$(dirname "$0")/..}" && pwd)
cd "$root" || exit 1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
passed=0 failed=0
pass() { passed=$((passed + 1)); echo "ok: $*"; }
fail() { failed=$((failed + 1)); echo "FAILED: $*"; }

# The stand-ins: executable regular files that fail if anything ever runs them.
mkdir -p "$work/bin"
for f in "$work/flatland" "$work/bin/gnuplot" "$work/bin/xvfb-run"; do
  printf '#!/bin/sh\necho "%s ran: the test runs no step" >&2\nexit 99\n' "$f" > "$f"
  chmod +x "$f"
done
printf 'not a program\n' > "$work/not-executable"
export PATH="$work/bin:$PATH"

# The scratch copy: reproduce.sh finds its repository as the directory above its own.
copy=$work/copy
mkdir -p "$copy/docs/tables" "$copy/build/reproduce"
cp docs/reproduce.sh "$copy/docs/"
cp docs/tables/*.md "$copy/docs/tables/"
echo "syndrome 5" > "$copy/build/reproduce/times.txt"

# Everything a run may write, as one checksum: the names under build/reproduce and docs/tables and
# the contents of their files and of the documents (a file or directory created, emptied or changed
# changes it).
state() {
  (cd "$1" && { find build/reproduce docs/tables 2>/dev/null | sort
                find build/reproduce docs/tables -type f 2>/dev/null | sort | xargs -r md5sum
                md5sum README.md docs/*.md 2>/dev/null; } | md5sum)
}

# refused WORD ENV... -- ARGS...: the invocation must be refused as bad input, naming WORD.
refused() {
  local word=$1 env=() args=() dir before after rc lines
  shift
  while [ "$1" != -- ]; do env+=("$1"); shift; done
  shift
  args=("$@")
  for dir in "$root" "$copy"; do
    local what="${env[*]:-} docs/reproduce.sh ${args[*]} (in ${dir/#$work/scratch})"
    before=$(state "$dir")
    env "${env[@]}" bash "$dir/docs/reproduce.sh" "${args[@]}" > "$work/out" 2> "$work/err"
    rc=$?
    after=$(state "$dir")
    lines=$(wc -l < "$work/err")
    if [ "$rc" != 2 ]; then fail "$what: exit status $rc, not 2"
    elif [ "$lines" != 1 ]; then fail "$what: $lines lines on stderr, not one: $(head -3 "$work/err")"
    elif ! grep -qF -- "$word" "$work/err"; then fail "$what: the message does not name '$word': $(cat "$work/err")"
    elif [ -s "$work/out" ]; then fail "$what: printed on stdout: $(head -3 "$work/out")"
    elif [ "$before" != "$after" ]; then fail "$what: changed build/reproduce, docs/tables or the documents"
    else pass "$what: exit 2, $(cat "$work/err")"
    fi
  done
}

ok=FLATLAND=$work/flatland
refused bogus-step "$ok" -- bogus-step
refused bogus-step "$ok" -- syndrome bogus-step
refused bogus-step "$ok" -- --quick bogus-step
refused width "$ok" -- --quick width
refused bogus-step "$ok" -- --dry-run bogus-step
refused bogus-step "$ok" -- --list bogus-step
refused --frobnicate "$ok" -- --frobnicate
refused --frobnicate "$ok" -- syndrome --frobnicate
refused -x "$ok" -- --quick -x
refused /tmp FLATLAND=/tmp -- --quick
refused /tmp FLATLAND=/tmp -- syndrome
refused /nonexistent FLATLAND=/nonexistent --
refused /nonexistent FLATLAND=/nonexistent -- --quick
refused "$work/not-executable" "FLATLAND=$work/not-executable" -- --quick

# Every step --list names runs: --dry-run accepts it, says it would run it, and writes nothing.
before=$(state "$root")
FLATLAND=$work/flatland bash docs/reproduce.sh --list > "$work/list" 2> "$work/err" ||
  fail "docs/reproduce.sh --list: exit status $?: $(cat "$work/err")"
names=$(grep -v '^ ' "$work/list" | awk '{print $1}')
[ -n "$names" ] || fail "docs/reproduce.sh --list names no step"
for name in $names; do
  out=$(FLATLAND=$work/flatland bash docs/reproduce.sh --dry-run "$name" 2>&1)
  rc=$?
  if [ "$rc" = 0 ] && grep -q "^  $name " <<< "$out"; then pass "--list names $name and --dry-run $name would run it"
  else fail "--list names $name but --dry-run $name gives exit status $rc: $out"
  fi
  # The lines under the name: the command, then what it writes or compares.
  block=$(awk -v n="$name" '$1 == n { on = 1; next } /^[^ ]/ { on = 0 } on' "$work/list")
  if grep -q -- '--quick' <<< "$block"; then
    out=$(FLATLAND=$work/flatland bash docs/reproduce.sh --dry-run --quick "$name" 2>&1)
    rc=$?
    if [ "$rc" = 0 ] && grep -q "^  $name .*compared" <<< "$out"; then pass "--dry-run --quick $name compares it"
    else fail "--list says --quick runs $name but --dry-run --quick $name gives exit status $rc: $out"
    fi
  fi
  command=$(sed -n 1p <<< "$block")
  for script in $(grep -oE '(docs|bench)/[A-Za-z0-9_./-]+\.(sh|py)' <<< "$command"); do
    if [ ! -f "$script" ]; then fail "$name runs $script, which does not exist"
    elif [[ $script == *.sh ]] && [ ! -x "$script" ]; then fail "$name runs $script, which is not executable"
    else pass "$name's script $script exists"
    fi
  done
done
# With no step named, --dry-run runs every step that writes, --quick every step it compares.
if out=$(FLATLAND=$work/flatland bash docs/reproduce.sh --dry-run 2>&1) && grep -q 'paste_tables.py$' <<< "$out"; then
  pass "--dry-run: the full run, then the tables pasted"
else fail "--dry-run: $out"
fi
if out=$(FLATLAND=$work/flatland bash docs/reproduce.sh --dry-run --quick 2>&1) && ! grep -q 'writes' <<< "$out" &&
   grep -q 'paste_tables.py --check$' <<< "$out"; then
  pass "--dry-run --quick: every step compared, then the pasted tables checked"
else fail "--dry-run --quick: $out"
fi
if [ "$before" = "$(state "$root")" ]; then pass "--list and --dry-run changed nothing"
else fail "--list or --dry-run changed build/reproduce, docs/tables or the documents"
fi

echo "$passed passed, $failed failed"
[ "$failed" = 0 ]

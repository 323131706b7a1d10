#!/usr/bin/env python3
"""Compares a table made again (docs/reproduce.sh --quick) with the committed one.

    docs/figures/compare_tables.py COMMITTED.md NEW.md [--exact | --tolerance]

Both are Markdown files of docs/tables. Rows are matched by their key cells: the cells of every
column whose header does not name a measurement (scene, method, photons, settings, ...); every
committed row must be made again, and no other. Times and rates (headers naming seconds, time,
rates per second, ns) depend on the machine and are never compared. Prints one line per row: its
numbers and how they agreed. Exit status 1 when a number disagrees, a row or table is missing or
added, or no row matches.

Same bits: the program gives the same bits for a given seed on any machine and thread count, so
when nothing that can change a number (src, CMakeLists.txt, bench, scenes2d, every *.py and *.sh:
what docs/reproduce.sh counts as a change) differs between the commit that made the committed
table (its first line names it) and the working tree, every cell but the times must be the very
same text, and so must the lines around the tables. --exact asks for that whatever git says.

Otherwise (--tolerance, or a change since, or a table made with uncommitted changes) every measured
number must agree within TOLERANCE (relative) with the committed one, which lets a change that
draws other random numbers (but solves the same problem) pass. Why 25 %: the tables quote medians
of 3 to 5 seeds of relative errors whose seed-to-seed spread is 10 to 40 % (the bars of the
time-to-accuracy plots); the median of 5 moves by about 1.25 x 30 % / sqrt(5) = 17 % for a change
of seeds. These tables keep no run of each seed, so the tolerance cannot follow each number's own
spread as docs/figures/time_to_accuracy/run.py --quick does. Differences from a closed form and
their sigma are noise by construction and only compared exactly (the measured value beside them
is compared instead)."""
import os, re, subprocess, sys

ROOT = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
TOLERANCE = 0.25
# Columns that name what a row is (matched exactly); every other column is a measurement.
KEYS = {"scene", "method", "storage", "basis", "estimator", "elements", "elements per curve", "photon origins",
        "positions", "rays", "width (m)", "photons", "budget", "rho", "transport", "step", "floor lit by", "angle",
        "angle (critical 41.810)", "wavelength", "`--elements`", "target", "N", "estimator, storage", "version"}
# Measurements never compared: times and rates (the machine's).
TIMES = re.compile(r"second|time|\bs\)|rays/s|photons/s|/s\b|\bns\b|per photon|rate|speed|wall", re.I)
# Measurements compared only exactly: differences from a closed form and their sigma (noise by
# construction), and counts that a change of the random numbers moves by design.
NOISE = re.compile(r"difference|measured - |sigma|^rounds$|^photons$", re.I)
NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
# What docs/reproduce.sh counts as a change that can move a number.
NUMBER_SOURCES = ["src", "CMakeLists.txt", "bench", "scenes2d", "*.py", "*.sh"]


def parse_tables(text):
    """Every Markdown table in `text`: (header cells, [row cells]), and the lines outside them
    (without the line docs/reproduce.sh heads a table file with)."""
    out, prose, cur = [], [], None
    for line in text.split("\n"):
        line = line.strip()
        if line.startswith("|") and line.endswith("|"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            if cur is None:
                cur = (cells, [])
                out.append(cur)
            elif not all(re.fullmatch(r":?-+:?", c) for c in cells):
                cur[1].append(cells)
        else:
            cur = None
            if line and not line.startswith("*Made by"):
                prose.append(line)
    return out, prose


def tables(path):
    """parse_tables of a file."""
    with open(path) as f:
        return parse_tables(f.read())


def number(cell):
    m = NUMBER.search(cell.replace(",", ""))
    return float(m.group(0)) if m else None


def same_bits_expected(committed):
    """(True, why) when the committed table was made at a commit from which nothing that can change
    a number has changed in the working tree; else (False, why)."""
    with open(committed) as f:
        m = re.search(r"at commit ([0-9a-f]{7,40})( \(with uncommitted changes\))?", f.readline())
    if not m:
        return False, "the committed table names no commit"
    if m.group(2):
        return False, "the committed table was made with uncommitted changes"
    p = subprocess.run(["git", "diff", "--quiet", m.group(1), "--"] + NUMBER_SOURCES, cwd=ROOT,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    if p.returncode == 0:
        return True, "nothing that can change a number changed since %s, which made it" % m.group(1)
    return False, "what can change a number changed since %s, which made it" % m.group(1)


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    committed, new = args[0], args[1]
    if "--exact" in sys.argv:
        exact, why = True, "--exact"
    elif "--tolerance" in sys.argv:
        exact, why = False, "--tolerance"
    else:
        exact, why = same_bits_expected(committed)
    (a, prose_a), (b, prose_b) = tables(committed), tables(new)
    name = committed.split("/")[-1]
    print("  %s: %s: %s" % (name, why, "every number the same text" if exact else
                            "every measured number within %.0f %%" % (100 * TOLERANCE)))
    compared, bad = 0, []
    if len(a) != len(b):
        bad.append("the committed file has %d tables, the new one %d" % (len(a), len(b)))
    if exact and prose_a != prose_b:
        bad.append("the lines around the tables differ: %s" % next(
            ("%r against committed %r" % (y, x) for x, y in zip(prose_a, prose_b) if x != y),
            "%d lines against committed %d" % (len(prose_b), len(prose_a))))
    for (ha, ra), (hb, rb) in zip(a, b):
        if ha != hb:
            bad.append("the columns differ: %s against %s" % (hb, ha))
            continue
        # "photons" names a row's budget, except beside a budget column (stiff: the photons shot).
        keyed = [h in KEYS and not (h == "photons" and "budget" in ha) for h in ha]
        index = {tuple(c for c, k in zip(r, keyed) if k): r for r in ra}
        made = set()
        for r in rb:
            key = tuple(c for c, k in zip(r, keyed) if k)
            old = index.get(key)
            label = " / ".join(key)
            if old is None:
                bad.append("%s: a row the committed table does not have" % label)
                continue
            made.add(key)
            same, notes = 0, []
            for h, k, x, y in zip(ha, keyed, old, r):
                if k or TIMES.search(h) or (not exact and NOISE.search(h)):
                    continue
                compared += 1
                vx, vy = number(x), number(y)
                if x == y:
                    same += 1
                elif exact or vx is None or vy is None:
                    notes.append("%s %s against committed %s: DISAGREES" % (h, y, x))
                    bad.append("%s, %s: %s against committed %s" % (label, h, y, x))
                else:
                    dev = abs(vx - vy) / max(abs(vx), abs(vy))
                    ok = dev <= TOLERANCE
                    notes.append("%s %s against committed %s (%.1f %%): %s" % (h, y, x, 100 * dev,
                                                                            "within" if ok else "DISAGREES"))
                    if not ok:
                        bad.append("%s, %s: %s against committed %s" % (label, h, y, x))
            print("    %s: %s" % (label, "; ".join(notes + (["%d the same text" % same] if same else [])) or "nothing measured"))
        for key in index:
            if key not in made:
                bad.append("%s: a committed row not made again" % " / ".join(key))
    if bad or compared == 0:
        print("  %s: %s" % (name, "no row matches the committed table" if compared == 0 else "DISAGREES"))
        for line in bad[:20]:
            print("    " + line)
        sys.exit(1)
    print("  %s: %d numbers compared, every one %s" % (name, compared, "the same text" if exact else
                                                       "the same text or within %.0f %%" % (100 * TOLERANCE)))


if __name__ == "__main__":
    main()

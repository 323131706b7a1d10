#!/usr/bin/env python3
"""Compares a table made again (docs/reproduce.sh --quick) with the committed one.

    docs/figures/compare_tables.py COMMITTED.md NEW.md

Both are Markdown files of docs/tables/. Rows are matched by their key cells: the cells of every
column whose header does not name a measurement (scene, method, photons, settings, ...). In matched
rows every measured number must agree within TOLERANCE (relative) with the committed one, except
times and rates (headers naming seconds, time, rates per second, ns), which depend on the machine.

Why 25 %: the program gives the same bits for a given seed on any machine and thread count, so at
the committed program the numbers agree exactly; the tolerance lets a change that draws other
random numbers (but solves the same problem) pass. The tables quote medians of 3 to 5 seeds of
relative errors whose seed-to-seed spread is 10 to 40 % (the bars of the time-to-accuracy plots);
the median of 5 moves by about 1.25 x 30 % / sqrt(5) = 17 % for a change of seeds. Exit status 1
when a number disagrees or no row matches."""
import re, sys

TOLERANCE = 0.25
# Columns that name what a row is (matched exactly); every other column is a measurement.
KEYS = {"scene", "method", "storage", "basis", "estimator", "elements", "elements per curve", "photon origins",
        "positions", "rays", "width (m)", "photons", "budget", "rho", "transport", "step", "floor lit by", "angle",
        "angle (critical 41.810)", "wavelength", "`--elements`", "target", "N", "estimator, storage", "version"}
# Measurements not compared: times and rates (the machine's), and differences from a closed form
# and their sigma (noise by construction: the measured value beside them is compared instead).
SKIP = re.compile(r"second|time|\bs\)|rays/s|photons/s|/s\b|\bns\b|per photon|rate|speed|wall|difference|"
                  r"measured - |sigma|^rounds$|^photons$", re.I)
NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def tables(path):
    """Every Markdown table in the file: (header cells, [row cells])."""
    out, cur = [], None
    for line in open(path):
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
    return out


def number(cell):
    m = NUMBER.search(cell.replace(",", ""))
    if not m:
        return None
    v = float(m.group(0))
    return v


def main():
    committed, new = sys.argv[1], sys.argv[2]
    a, b = tables(committed), tables(new)
    compared, bad = 0, []
    for (ha, ra), (hb, rb) in zip(a, b):
        if ha != hb:
            bad.append("the columns differ: %s against %s" % (ha, hb))
            continue
        keyed = [h in KEYS for h in ha]
        measured = [not k and not SKIP.search(h) for h, k in zip(ha, keyed)]
        index = {tuple(c for c, k in zip(r, keyed) if k): r for r in ra}
        for r in rb:
            key = tuple(c for c, k in zip(r, keyed) if k)
            old = index.get(key)
            if old is None:
                continue
            for h, m, x, y in zip(ha, measured, old, r):
                if not m:
                    continue
                vx, vy = number(x), number(y)
                if vx is None or vy is None:
                    if x != y:
                        bad.append("%s, %s: %r against committed %r" % (" / ".join(key), h, y, x))
                    continue
                compared += 1
                scale = max(abs(vx), abs(vy))
                if scale > 0 and abs(vx - vy) > TOLERANCE * scale:
                    bad.append("%s, %s: %s against committed %s" % (" / ".join(key), h, y, x))
    name = committed.split("/")[-1]
    if bad or compared == 0:
        print("  %s: %s" % (name, "no row matches the committed table" if compared == 0 else "DISAGREES"))
        for line in bad[:20]:
            print("    " + line)
        sys.exit(1)
    print("  %s: %d numbers within %.0f %% of the committed table" % (name, compared, 100 * TOLERANCE))


if __name__ == "__main__":
    main()

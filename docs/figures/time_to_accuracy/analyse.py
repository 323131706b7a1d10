#!/usr/bin/env python3
"""Issue 12, part 5: read DIR/<scene>/convergence.csv (written by run.sh) and print the time-to-accuracy
table in markdown; write DIR/<scene>/medians.dat and draw DIR/<scene>.png (gnuplot) of the median error
against the median solve time. Standard library only.

Time to a target error: the median (over seeds) of rel_l2 and of the solve time at each photon budget;
the first pair of consecutive budgets whose median errors bracket the target, interpolated linearly in
log(error) against log(time). Never extrapolated: "not reached" names the largest budget measured,
"< t" means the smallest budget was already below the target (t its median time)."""
import csv, math, os, statistics, subprocess, sys

SCENES = ["penumbra", "round_occluder", "lit_ring", "ring_profile", "curved_room"]
BASES = [("constant", "classic"), ("linear", "linear"), ("cubic", "cubic"), ("hermite", "hermite")]
SAMPLERS = ["random", "sobol"]
TARGETS = [1e-2, 1e-3]


def key_of(method):
    kv = dict(p.split("=", 1) for p in method.split("+"))
    return kv.get("basis", "cubic"), kv.get("sampler", "random")


BUDGETS = [float(b) for b in os.environ.get("BUDGETS", "1e4,3e4,1e5,3e5,1e6,3e6,1e7").split(",")]


THREADS = os.environ.get("THREADS", "2")
THREADS_LABEL = "1 thread" if THREADS == "1" else THREADS + " threads"
EXTEND = [float(b) for b in os.environ.get("EXTEND", "3e7").split(",") if b]


def load(path, budgets=None):
    """Medians per method and budget. The CSV holds the photons actually shot, which are not the budget
    (the rounds cut it: on the penumbra 1e4 and 3e4 both shoot 8192), so the budget of a row is taken
    from its position: converge writes each method's budgets in order, seeds 1..S within each."""
    runs = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            k = key_of(r["method"])
            groups = runs.setdefault(k, [])
            if int(r["seed"]) == 1 or not groups:
                groups.append([])
            groups[-1].append((float(r["seconds"]), float(r["rel_l2"]), float(r["photons"])))
    med = {}
    for k, groups in runs.items():
        rows = []
        for i, v in enumerate(groups):
            es = [e for _, e, _ in v]
            rows.append(((budgets or BUDGETS)[i], statistics.median(t for t, _, _ in v), statistics.median(es), min(es),
                         max(es), len(v), statistics.median(n for _, _, n in v)))
        med[k] = rows
    return med


def time_to(rows, target):
    """(seconds, kind): kind '' interpolated, '<' below target at the smallest budget, '>' not reached."""
    if rows[0][2] <= target:
        return rows[0][1], "<"
    for a, b in zip(rows, rows[1:]):
        if a[2] > target >= b[2]:
            f = (math.log(target) - math.log(a[2])) / (math.log(b[2]) - math.log(a[2]))
            return math.exp(math.log(a[1]) + f * (math.log(b[1]) - math.log(a[1]))), ""
    return rows[-1][1], ">"


def slope(rows, last=3):
    """Least-squares slope of log(median error) against log(photons shot) over the last `last` budgets."""
    pts = [(math.log(r[6]), math.log(r[2])) for r in rows[-last:]]
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    return sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)


def fmt_t(tk, rows):
    t, kind = tk
    if kind == ">":
        return "not reached by %s photons" % fmt_n(rows[-1][0])
    s = "%.3g s" % t
    return "< " + s if kind == "<" else s


def fmt_n(n):
    e = int(math.floor(math.log10(n) + 1e-9))
    m = n / 10 ** e
    return ("1e%d" % e) if abs(m - 1) < 0.05 else ("%.0fe%d" % (m, e))


def ratio(slow, fast):
    """How many times faster `fast` reaches the target than `slow`; '>' when only slow's bound is known."""
    (ts, ks), (tf, kf) = slow, fast
    if kf == ">":
        return "–" if ks == ">" else "cubic not reached"
    if kf == "<" and ks == "<":
        return "both < smallest budget"
    if ks == ">":
        return "> %.3gx" % (ts / tf)
    if kf == "<":
        return "> %.3gx" % (ts / tf)
    return "%.3gx" % (ts / tf)


def plot(d, scene, med):
    dat = os.path.join(d, scene, "medians.dat")
    with open(dat, "w") as f:
        for b, _ in BASES:
            for s in SAMPLERS:
                f.write("# %s %s: budget seconds median_rel_l2 min max seeds photons_shot\n" % (b, s))
                for row in med.get((b, s), []):
                    f.write("%g %.6g %.6g %.6g %.6g %d %.6g\n" % row)
                f.write("\n\n")
    colours = ["#7f7f7f", "#1f77b4", "#d62728", "#2ca02c"]
    lines = []
    i = 0
    for (b, label), c in zip(BASES, colours):
        for s in SAMPLERS:
            dt = 1 if s == "random" else 2
            lines.append("'%s' index %d using 2:3 with linespoints lw 2 dt %d pt %d lc rgb '%s' title '%s %s'"
                         % (dat, i, dt, 7 if s == "random" else 6, c, label, s))
            i += 1
    gp = """set terminal pngcairo size 560,420 font ',9'
set output '%s'
set logscale xy
set format x '10^{%%L}'; set format y '10^{%%L}'
set xlabel 'median solve time (s, %s)'; set ylabel 'median relative L2 error of B - E'
set title '%s: error against time, medians of seeds'
set key bottom left
set grid
plot 0.01 with lines lc rgb '#bbbbbb' dt 3 notitle, 0.001 with lines lc rgb '#bbbbbb' dt 3 notitle, \\
 %s
""" % (os.path.join(d, scene + ".png"), THREADS_LABEL, scene.replace("_", " "), ", \\\n ".join(lines))
    subprocess.run(["gnuplot"], input=gp.encode(), check=True)


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    data = {}
    for sc in SCENES:
        p = os.path.join(d, sc, "convergence.csv")
        if os.path.exists(p):
            data[sc] = load(p)
            # run.sh's extension: more photons for some methods (DIR/<scene>/extend/convergence.csv)
            pe = os.path.join(d, sc, "extend", "convergence.csv")
            if os.path.exists(pe) and EXTEND:
                for k, rows in load(pe, EXTEND).items():
                    data[sc][k] = sorted(data[sc][k] + rows)
            plot(d, sc, data[sc])
    print("| scene | method | to 1 %, random | to 1 %, sobol | to 0.1 %, random | to 0.1 %, sobol |"
          " slope (last 3 budgets), random / sobol |")
    print("|---|---|---|---|---|---|---|")
    tt = {}
    for sc, med in data.items():
        for b, label in BASES:
            cells = []
            for target in TARGETS:
                for s in SAMPLERS:
                    rows = med.get((b, s))
                    if not rows:
                        cells.append("–"); continue
                    tt[sc, b, s, target] = time_to(rows, target)
                    cells.append(fmt_t(tt[sc, b, s, target], rows))
            sl = " / ".join("%.2f" % slope(med[(b, s)]) if (b, s) in med else "–" for s in SAMPLERS)
            print("| %s | %s | %s | %s |" % (sc.replace("_", " "), label, " | ".join(cells), sl))
    print()
    print("Speed-up of cubic at 0.1 % (time of the other method / time of cubic, same sampler; "
          "'>' when the other method did not reach 0.1 %, bounded by its time at the largest budget):")
    print()
    print("| scene | cubic vs linear, random | cubic vs linear, sobol | cubic vs classic, random |"
          " cubic vs classic, sobol |")
    print("|---|---|---|---|---|")
    for sc in data:
        cells = []
        for other in ["linear", "constant"]:
            for s in SAMPLERS:
                k1, k2 = (sc, other, s, 1e-3), (sc, "cubic", s, 1e-3)
                cells.append(ratio(tt[k1], tt[k2]) if k1 in tt and k2 in tt else "–")
        print("| %s | %s |" % (sc.replace("_", " "), " | ".join(cells)))
    print()
    print("Not measured, extrapolated: where a method did not reach 0.1 %, the time it would need if its error "
          "kept falling at the slope (against time) of its last three budgets; 'floor' where that slope is "
          "flatter than -0.2 (bias-limited: more photons do not help).")
    print()
    print("| scene | classic, random | classic, sobol | linear, random | linear, sobol | cubic, random |"
          " cubic, sobol | hermite, random | hermite, sobol |")
    print("|---|---|---|---|---|---|---|---|---|")
    for sc, med in data.items():
        cells = []
        for b, _ in BASES:
            for smp in SAMPLERS:
                rows = med.get((b, smp))
                if not rows:
                    cells.append("–"); continue
                t, kind = time_to(rows, 1e-3)
                if kind != ">":
                    cells.append("(measured %.3g s)" % t); continue
                pts = [(math.log(r[1]), math.log(r[2])) for r in rows[-3:]]
                mx = sum(x for x, _ in pts) / 3; my = sum(y for _, y in pts) / 3
                st = sum((x - mx) * (y - my) for x, y in pts) / sum((x - mx) ** 2 for x, _ in pts)
                if st > -0.2:
                    cells.append("floor (%.2g)" % rows[-1][2]); continue
                cells.append("~%.3g s" % (rows[-1][1] * (1e-3 / rows[-1][2]) ** (1 / st)))
        print("| %s | %s |" % (sc.replace("_", " "), " | ".join(cells)))
    print()
    print("Median error (median solve time) per photon budget:")
    for sc, med in data.items():
        print()
        budgets = sorted({r[0] for rows in med.values() for r in rows})
        print("%s | %s" % (sc, " | ".join(fmt_n(n) for n in budgets)))
        for b, label in BASES:
            for s in SAMPLERS:
                rows = {r[0]: r for r in med.get((b, s), [])}
                print("  %-8s %-6s | %s" % (label, s, " | ".join(
                    "%.3g (%.3gs)" % (rows[n][2], rows[n][1]) if n in rows else "–" for n in budgets)))


if __name__ == "__main__":
    main()

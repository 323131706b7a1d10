#!/usr/bin/env python3
"""Time to accuracy: the headline experiment of docs/experiments.md and the README's table.

Every method below is solved at every photon budget and seed on five scenes by `flatland converge`
against a reference of each scene (`flatland reference` at a pinned resolution), and the median
relative L2 error of B - E is read against the median solve time. Every solver setting is spelled
out in the method strings, so a change of the program's defaults does not change what is measured.

    docs/figures/time_to_accuracy/run.py [--quick] [--tables DIR]

Writes, per scene, DIR/<scene>/convergence.csv (every run), converge.txt, reference.txt and
DIR/<scene>.png (median error against median time, one line per method, legend below the axes,
the 1 % and 0.1 % targets and the reference's own error drawn); and the tables
  TABLES/time-to-accuracy.md        time to 1 % and 0.1 %, error at 1e6 photons, cost per photon
  TABLES/time-to-accuracy-errors.md median error per budget (every number the plots show)
  TABLES/walks.md                   random walks against shooting (same scenes, same references)
  TABLES/readme-answer.md           the README's summary
--quick solves a subset (two scenes, four methods, budgets 1e4 .. 1e6) into a scratch directory
and compares each run's error with the committed convergence.csv (see compare_quick); it exits 1
when they disagree. Environment: FLATLAND (default build/flatland), THREADS (default 2)."""
import argparse, csv, math, os, re, statistics, subprocess, sys, tempfile, time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
FLATLAND = os.environ.get("FLATLAND", "build/flatland")
THREADS = os.environ.get("THREADS", "2")
SEEDS = 5
BUDGETS = os.environ.get("TTA_BUDGETS", "1e4,3e4,1e5,3e5,1e6,3e6,1e7").split(",")  # TTA_*: for testing the script
TARGETS = [1e-2, 1e-3]
FIXED_BUDGET = 1e6  # the README's "error at a fixed budget"

# Scene name -> (scene file, reference resolution N: elements no longer than scene size / N). N is
# chosen so that the reference's own estimated error is at least 10x below every median error the
# scene's runs are judged by; check_reference says whether it is, at every run.
SCENES = {
    "penumbra": ("scenes2d/penumbra.json", 400),  # reproduced to round-off at any N
    "round_occluder": ("scenes2d/tests/reference_round_occluder.json", 1600),
    "lit_ring": ("docs/figures/time_to_accuracy/lit_ring.json", 1600),
    "ring_profile": ("scenes2d/tests/reference_ring_profile.json", 800),
    "curved_room": ("scenes2d/curved_room.json", 1600),
}

# Settings common to every method; each method names the rest. "elements=16" is the paper's fixed
# mesh (16 elements per curve); "auto" lets each curve's mesh follow its photons.
COMMON = "discontinuities=auto+sampling=reconstructed+ray-width=0+transport=shooting"
DEFAULT_ESTIMATOR = {"constant": "galerkin", "linear": "galerkin", "cubic": "galerkin", "hermite": "local"}
METHODS = []  # (label, family, basis, method string)
for basis in ["constant", "linear", "cubic", "hermite"]:
    METHODS.append((basis, "default", basis, "basis=%s+estimator=%s+elements=auto+sampler=sobol+%s"
                    % (basis, DEFAULT_ESTIMATOR[basis], COMMON)))
for basis in ["constant", "linear", "cubic", "hermite"]:
    METHODS.append((basis + ", paper", "paper", basis,
                    "basis=%s+estimator=lumped+elements=16+sampler=random+%s" % (basis, COMMON)))
CLASSIC = ("basis=constant+estimator=lumped+elements=16+sampler=random+discontinuities=none+sampling=uniform"
           "+ray-width=0+transport=shooting")
METHODS.append(("classic", "classic", "constant", CLASSIC))
METHODS.append(("cubic, walks", "walk", "cubic", "basis=cubic+estimator=galerkin+elements=auto+sampler=sobol"
                "+discontinuities=auto+sampling=reconstructed+ray-width=0+transport=walk"))
for _name in [n for n in SCENES if n not in os.environ.get("TTA_SCENES", ",".join(SCENES)).split(",")]:
    del SCENES[_name]
QUICK_SCENES = ["penumbra", "round_occluder"]
QUICK_METHODS = ["linear", "cubic", "cubic, paper", "classic"]
QUICK_BUDGETS = ["1e4", "1e5", "1e6"]


def run(cmd, out_path=None):
    """Runs a command from the repository's top; its output to out_path (or this script's stderr)."""
    p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if p.returncode != 0:
        sys.stderr.write(p.stdout + p.stderr)
        sys.exit("failed (exit %d): %s" % (p.returncode, " ".join(cmd)))
    if out_path:
        with open(os.path.join(ROOT, out_path), "w") as f:
            f.write(p.stdout)
    return p.stdout


def solve_scene(name, out, methods, budgets):
    scene, n = SCENES[name]
    os.makedirs(out, exist_ok=True)
    # Paths relative to the repository's top (the commands run there), so that the logs kept
    # beside the runs name no directory of the machine that made them.
    out = os.path.relpath(out, ROOT) if out.startswith(ROOT + os.sep) else out
    ref = os.path.join(out, "reference.json")
    run([FLATLAND, "reference", scene, "--elements", str(n), "--threads", THREADS, "--out", ref],
        os.path.join(out, "reference.txt"))
    text = run([FLATLAND, "converge", scene, "--reference", ref, "--methods", ",".join(m[3] for m in methods),
                "--budgets", ",".join(budgets), "--seeds", str(SEEDS), "--threads", THREADS,
                "--samples", "100", "--out", out], os.path.join(out, "converge.txt"))
    # converge's own plot (every method, its legend) is kept under the converge name
    return text


def floor_of(out):
    """The reference's estimated error in the measure the runs are judged by (converge prints it)."""
    with open(os.path.join(out, "converge.txt")) as f:
        m = re.search(r"reference error \(estimated\) ([0-9.eE+-]+) relative L2", f.read())
    return float(m.group(1)) if m else 0.0


def load(path, methods, budgets):
    """{label: [(budget, median seconds, median error, min, max, median photons, errors by seed)]}.
    converge writes each method's budgets in order, seeds 1..S within each; the budget of a row is
    taken from its position (the rounds round the photons shot, so they do not name the budget)."""
    by_method = {m[3]: m[0] for m in methods}
    runs = {}
    with open(path) as f:
        for r in csv.DictReader(f):
            label = by_method[r["method"]]
            groups = runs.setdefault(label, [])
            if int(r["seed"]) == 1 or not groups:
                groups.append([])
            groups[-1].append((float(r["seconds"]), float(r["rel_l2"]), float(r["photons"]), int(r["seed"])))
    med = {}
    for label, groups in runs.items():
        rows = []
        for i, g in enumerate(groups):
            es = [e for _, e, _, _ in g]
            rows.append((float(budgets[i]), statistics.median(t for t, _, _, _ in g), statistics.median(es), min(es),
                         max(es), statistics.median(n for _, _, n, _ in g), {s: e for _, e, _, s in g}))
        med[label] = rows
    return med


def time_to(rows, target):
    """(seconds, kind): kind '' interpolated (log error against log time between the two budgets whose
    median errors bracket the target), '<' already below at the smallest budget, '>' not reached."""
    if rows[0][2] <= target:
        return rows[0][1], "<"
    for a, b in zip(rows, rows[1:]):
        if a[2] > target >= b[2]:
            f = (math.log(target) - math.log(a[2])) / (math.log(b[2]) - math.log(a[2]))
            return math.exp(math.log(a[1]) + f * (math.log(b[1]) - math.log(a[1]))), ""
    return rows[-1][1], ">"


def fmt_t(tk):
    t, kind = tk
    if kind == ">":
        return "–"
    s = "%.2g s" % t if t < 10 else "%.0f s" % t
    return "< " + s if kind == "<" else s


def fmt_e(e):
    return "%.2g %%" % (100 * e)


def nice(name):
    return name.replace("_", " ")


def plot(out_png, scene, med, floor):
    """Median error against median time, one line per method; legend below the axes."""
    dat = out_png[:-4] + ".dat"
    styles = {"default": (1, 7), "paper": (2, 6), "classic": (1, 5), "walk": (4, 9)}
    colours = {"constant": "#7f7f7f", "linear": "#1f77b4", "cubic": "#d62728", "hermite": "#2ca02c"}
    lines, i = [], 0
    with open(dat, "w") as f:
        for label, family, basis, _ in METHODS:
            if label not in med:
                continue
            f.write("# %s: budget seconds median_rel_l2 min max photons\n" % label)
            for r in med[label]:
                f.write("%g %.6g %.6g %.6g %.6g %.6g\n" % r[:6])
            f.write("\n\n")
            dt, pt = styles[family]
            colour = "#000000" if family == "classic" else ("#9467bd" if family == "walk" else colours[basis])
            title = {"default": "%s (defaults: Galerkin, auto mesh, Sobol')" % basis,
                     "paper": "%s, paper (lumped, 16 elements, random)" % basis,
                     "classic": "classic (constant, lumped, 16 elements, uniform origins, no events, random)",
                     "walk": "cubic, random walks (defaults)"}[family]
            lines.append("'%s' index %d using 2:3:4:5 with yerrorlines lw 2 dt %d pt %d ps 0.8 lc rgb '%s' title \"%s\" noenhanced"
                         % (os.path.basename(dat), i, dt, pt, colour, title))
            i += 1
    lines.append("0.01 with lines lc rgb '#444444' dt 2 lw 1 title 'targets: 1 % and 0.1 %'")
    lines.append("0.001 with lines lc rgb '#444444' dt 2 lw 1 notitle")
    smallest = min(r[3] for rows in med.values() for r in rows)
    label = ""
    if 0 < floor < 0.01 * smallest:  # drawn, it would only stretch the axis: said in a label
        label = "set label 1 'reference error (estimated) %.2g: far below the plot' at graph 0.02, graph 0.04\n" % floor
    elif floor > 0:
        lines.append("%.6g with lines lc rgb '#000000' dt 4 lw 1.5 title 'reference error (estimated) %.2g'"
                     % (floor, floor))
    gp = """set terminal pngcairo size 760,%d font ',9'
set output '%s'
set logscale xy
set format x '10^{%%L}'; set format y '10^{%%L}'
set xlabel 'median solve time (s, %s thread(s))'
set ylabel 'median relative L2 error of B - E'
set title '%s: error against solve time, median of %d seeds (bars: min to max)'
set key below vertical maxcols 2 Left reverse
set grid
%splot %s
""" % (480 + 16 * ((len(lines) + 1) // 2), os.path.basename(out_png), THREADS, nice(scene), SEEDS,
       label, ", \\\n ".join(lines))
    subprocess.run(["gnuplot"], input=gp.encode(), check=True, cwd=os.path.dirname(out_png))
    os.remove(dat)


def check_reference(scene, med, floor):
    """The reference's own error must be at least 10x below the smallest median error it judges."""
    smallest = min(r[2] for rows in med.values() for r in rows)
    ok = floor * 10 <= smallest
    ratio = smallest / floor if floor > 0 else float("inf")
    return ok, "%s: reference error %.2g, smallest median error judged %.2g (%s): %s" % (
        nice(scene), floor, smallest, "%.0fx" % ratio if ratio < 1e4 else "more than 1e4x",
        "good enough" if ok else "NOT 10x below")


def cost_per_photon(rows):
    """Median seconds per photon shot at the largest budget (ns)."""
    r = rows[-1]
    return 1e9 * r[1] / r[5]


def tables(d, tdir):
    data, floors, checks = {}, {}, []
    for name in SCENES:
        out = os.path.join(d, name)
        data[name] = load(os.path.join(out, "convergence.csv"), METHODS, BUDGETS)
        floors[name] = floor_of(out)
        plot(os.path.join(d, name + ".png"), name, data[name], floors[name])
        checks.append(check_reference(name, data[name], floors[name]))
    labels = [m[0] for m in METHODS if m[2] != "walk"]
    shooting = [m for m in METHODS if m[1] != "walk"]

    lines = []
    w = lines.append
    w("Time to a relative L2 error of B - E of 1 %% and 0.1 %% (median over %d seeds; '–': not reached by 1e7"
      " photons), error at %s photons, and cost per photon at 1e7 photons, %s thread(s):" % (SEEDS, "1e6", THREADS))
    w("")
    w("| scene | method | to 1 % | to 0.1 % | error at 1e6 photons | ns per photon |")
    w("|---|---|---|---|---|---|")
    for name, med in data.items():
        for label, family, basis, _ in shooting:
            rows = med[label]
            at = [r for r in rows if r[0] == FIXED_BUDGET][0]
            w("| %s | %s | %s | %s | %s | %.0f |" % (nice(name), label, fmt_t(time_to(rows, 1e-2)),
                                                     fmt_t(time_to(rows, 1e-3)), fmt_e(at[2]), cost_per_photon(rows)))
    w("")
    w("References (the check every comparison makes): " + "; ".join(c[1] for c in checks) + ".")
    write(tdir, "time-to-accuracy", lines)

    lines = []
    w = lines.append
    w("Median relative L2 error of B - E (median solve time) per photon budget, %d seeds:" % SEEDS)
    for name, med in data.items():
        w("")
        w("| %s | %s |" % (nice(name), " | ".join(BUDGETS)))
        w("|---|%s" % ("---|" * len(BUDGETS)))
        for label, _, _, _ in METHODS:
            w("| %s | %s |" % (label, " | ".join("%.3g (%.2g s)" % (r[2], r[1]) for r in med[label])))
    write(tdir, "time-to-accuracy-errors", lines)

    lines = []
    w = lines.append
    w("Cubic storage with the defaults, by progressive shooting and by random walks (budget: photons or"
      " walks), %d seeds, %s thread(s):" % (SEEDS, THREADS))
    w("")
    w("| scene | transport | to 1 % | to 0.1 % | error at 1e6 | error at 1e7 | ns per photon or walk |")
    w("|---|---|---|---|---|---|---|")
    for name, med in data.items():
        for label, tname in [("cubic", "shooting"), ("cubic, walks", "walks")]:
            rows = med[label]
            w("| %s | %s | %s | %s | %s | %s | %.0f |" % (nice(name), tname, fmt_t(time_to(rows, 1e-2)),
                                                          fmt_t(time_to(rows, 1e-3)), fmt_e(rows[-3][2]),
                                                          fmt_e(rows[-1][2]), cost_per_photon(rows)))
    both = [n for n in data if all(time_to(data[n][l], 1e-3)[1] != ">" for l in ("cubic", "cubic, walks"))]
    w("")
    w("Shooting reaches 0.1 %% %s sooner than walks on %s; neither gets there by 1e7 on %s." % (
        ", ".join("%.1fx" % (time_to(data[n]["cubic, walks"], 1e-3)[0] / time_to(data[n]["cubic"], 1e-3)[0])
                  for n in both),
        ", ".join(nice(n) for n in both) or "no scene",
        ", ".join(nice(n) for n in data if n not in both and time_to(data[n]["cubic"], 1e-3)[1] == ">"
                  and time_to(data[n]["cubic, walks"], 1e-3)[1] == ">") or "no scene"))
    write(tdir, "walks", lines)

    # The README's answer: per method, the time to 1 % and to 0.1 % on each scene, the error at 1e6
    # photons as the geometric mean over the scenes, and the cost per photon against linear's.
    lines = []
    w = lines.append
    w("| method | %s | error at 1e6 photons (geometric mean) | time per photon / linear's |"
      % " | ".join(nice(n) for n in data))
    w("|---|%s---|---|" % ("---|" * len(data)))
    for label, family, basis, _ in shooting:
        cells = []
        for name, med in data.items():
            rows = med[label]
            cells.append("%s / %s" % (fmt_t(time_to(rows, 1e-2)), fmt_t(time_to(rows, 1e-3))))
        gm = math.exp(statistics.mean(math.log([r for r in med[label] if r[0] == FIXED_BUDGET][0][2])
                                      for med in data.values()))
        base = "linear" if family == "default" else "linear, paper"
        cost = statistics.median(cost_per_photon(med[label]) / cost_per_photon(med[base]) for med in data.values())
        w("| %s | %s | %s | %.2fx |" % ("**%s**" % label if label == "cubic, paper" else label, " | ".join(cells),
                                        fmt_e(gm), cost))
    write(tdir, "readme-answer", lines)
    write(tdir, "time-to-accuracy-findings", findings(data))
    return all(c[0] for c in checks)


def findings(data):
    """The table's answers as sentences, computed here so that no number in them is typed."""
    names = list(data)
    out = []
    w = out.append
    reach = {label: [n for n in names if time_to(data[n][label], 1e-3)[1] != ">"] for label, _, _, _ in METHODS}
    for label in ["constant", "linear", "cubic", "hermite"]:
        w("- **%s** (defaults) reaches 0.1 %% on %s." % (
            label, ", ".join(nice(n) for n in reach[label]) if reach[label] else "no scene"))
    both = [n for n in names if n in reach["cubic"] and n in reach["linear"]]
    if both:
        w("- Linear storage needs %s the time cubic needs to 0.1 %% (%s)." % (
            ", ".join("%.1fx" % (time_to(data[n]["linear"], 1e-3)[0] / time_to(data[n]["cubic"], 1e-3)[0]) for n in both),
            ", ".join(nice(n) for n in both)))
    worse = [n for n in names if data[n]["cubic"][-1][2] > data[n]["linear"][-1][2]]
    w("- At 1e7 photons cubic's error is %s." % (
        "below linear's on every scene" if not worse else "above linear's on %s (%s)" % (
            ", ".join(nice(n) for n in worse),
            ", ".join("%.2g %% against %.2g %%" % (100 * data[n]["cubic"][-1][2], 100 * data[n]["linear"][-1][2])
                      for n in worse))))
    ratio = statistics.median(cost_per_photon(data[n]["cubic"]) / cost_per_photon(data[n]["linear"]) for n in names)
    w("- A photon costs cubic storage %.2fx what it costs linear (median over the scenes, at 1e7 photons)." % ratio)
    floors = [label for label, family, _, _ in METHODS if family in ("paper", "classic")]
    stuck = [n for n in names if all(time_to(data[n][l], 1e-2)[1] == ">" for l in floors)]
    w("- With the paper's lumped deposits on 16 fixed elements no storage reaches 1 %% on %s: the error stops "
      "at the mesh's bias (cubic, paper, at 1e7 photons: %s)." % (
          ", ".join(nice(n) for n in stuck) if stuck else "any scene",
          ", ".join("%s %.2g %%" % (nice(n), 100 * data[n]["cubic, paper"][-1][2]) for n in names)))
    gain = statistics.median(data[n]["cubic, paper"][-1][2] / data[n]["cubic"][-1][2] for n in names)
    w("- At 1e7 photons the defaults' cubic error is %.0fx below the paper's method's (median over the scenes)."
      % gain)
    return out


def write(tdir, name, lines):
    with open(os.path.join(tdir, name + ".md"), "w") as f:
        f.write("\n".join(lines) + "\n")


def compare_quick(d, scratch):
    """Each quick run against the committed run of the same scene, method, budget and seed. The program
    gives the same bits for a seed on any machine and thread count, so at the committed program the
    two agree exactly; after a change that alters the random stream but not the method, the medians may
    move by the seeds' spread. Tolerance: |log(median quick / median committed)| at most 3 times the
    standard deviation of the log errors over the committed seeds plus 0.05 (numbers near round-off
    differ by more than their spread says)."""
    bad = 0
    methods = [m for m in METHODS if m[0] in QUICK_METHODS]
    for name in QUICK_SCENES:
        full = load(os.path.join(d, name, "convergence.csv"), METHODS, BUDGETS)
        quick = load(os.path.join(scratch, name, "convergence.csv"), methods, QUICK_BUDGETS)
        for label in QUICK_METHODS:
            for q in quick[label]:
                f = [r for r in full[label] if r[0] == q[0]][0]
                logs = [math.log(e) for e in f[6].values()]
                tol = 3 * statistics.stdev(logs) + 0.05
                dev = abs(math.log(q[2] / f[2]))
                same = q[6] == f[6]
                verdict = "same bits" if same else ("within" if dev <= tol else "DISAGREES")
                bad += verdict == "DISAGREES"
                print("  %-15s %-14s %-5g quick %.4g committed %.4g |log ratio| %.3f tolerance %.3f: %s"
                      % (name, label, q[0], q[2], f[2], dev, tol, verdict))
    return bad == 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--tables", default=os.path.join(ROOT, "docs", "tables"))
    ap.add_argument("--tables-only", action="store_true", help="no solves: tables and plots from the CSVs")
    a = ap.parse_args()
    subprocess.run([sys.executable, os.path.join(HERE, "make_lit_ring.py")], check=True, stdout=subprocess.DEVNULL)
    if a.quick:
        scratch = tempfile.mkdtemp(prefix="flatland-quick-")
        methods = [m for m in METHODS if m[0] in QUICK_METHODS]
        for name in QUICK_SCENES:
            t = time.time()
            solve_scene(name, os.path.join(scratch, name), methods, QUICK_BUDGETS)
            print("  %s: %.0f s" % (name, time.time() - t))
        ok = compare_quick(HERE, scratch)
        print("time to accuracy, quick: %s" % ("agrees with the committed runs" if ok else "DISAGREES"))
        sys.exit(0 if ok else 1)
    if not a.tables_only:
        for name in SCENES:
            t = time.time()
            solve_scene(name, os.path.join(HERE, name), METHODS, BUDGETS)
            print("%s: %.0f s" % (name, time.time() - t), file=sys.stderr)
    os.makedirs(a.tables, exist_ok=True)
    ok = tables(HERE, a.tables)
    if not ok:
        sys.exit("a reference is not 10x more accurate than the errors it judges (see time-to-accuracy.md)")


if __name__ == "__main__":
    main()

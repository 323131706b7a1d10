#!/usr/bin/env python3
"""Time to accuracy: the headline experiment of docs/experiments.md and the README's table.

Every method below is solved at every photon budget and seed on five scenes by `flatland converge`
against a reference of each scene (`flatland reference` at a pinned resolution), and the median
relative L2 error of B - E is read against the median solve time. Every solver setting is spelled
out in the method strings, so a change of the program's defaults does not change what is measured.

    docs/figures/time_to_accuracy/run.py [--quick] [--tables DIR]

The paper's settings run on fixed meshes of 16, 64 and 256 elements per curve (PAPER_MESHES), and
the tables and plots report them on their best fixed mesh for each budget (the mesh with the least
median error there, chosen with hindsight: add_envelopes), beside the 16-element setting.

Writes, per scene, DIR/<scene>/convergence.csv (every run but the paper's settings on meshes finer
than 16 elements, which are in DIR/<scene>/meshes/convergence.csv: see MESHES_DIR), converge.txt,
reference.txt and DIR/<scene>.png (median error against median time, one line per method, the
paper's settings on their best fixed mesh per budget, legend below the axes, the 1 % and 0.1 %
targets and the reference's own error drawn); and the tables
  TABLES/time-to-accuracy.md        time to 1 % and 0.1 %, error at 1e6 photons (with its
                                    interquartile range over the seeds), cost per photon
  TABLES/time-to-accuracy-errors.md median error per budget with its interquartile range, every
                                    mesh of the paper's settings on its own row (every number the
                                    plots show)
  TABLES/walks.md                   random walks against shooting (same scenes, same references)
  TABLES/readme-answer.md           the README's summary
--quick makes the five tables again from the committed runs (no solve) and compares them with
TABLES (see compare_with_runs), then solves a subset (two scenes, four methods, budgets 1e4 .. 1e6)
into a scratch directory and compares each run with the committed convergence.csv and each median
with the numbers of the Markdown tables in TABLES (see compare_quick); it prints every comparison
and exits 1 when one disagrees. Environment: FLATLAND (default build/flatland), THREADS (default 2)."""
import argparse, csv, math, os, re, shutil, statistics, subprocess, sys, tempfile, time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
sys.path.insert(0, os.path.dirname(HERE))  # docs/figures: the Markdown table parser
from compare_tables import parse_tables  # noqa: E402
import spread  # noqa: E402
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

# Settings common to every method; each method names the rest. "elements=N" is a fixed mesh of N
# elements per curve; "auto" lets each curve's mesh follow its photons.
COMMON = ("discontinuities=auto+sampling=reconstructed+ray-width=0+transport=shooting+gather=none"
          "+control-variate=none")
DEFAULT_ESTIMATOR = {"constant": "galerkin", "linear": "galerkin", "cubic": "galerkin", "hermite": "local"}
BASES = ["constant", "linear", "cubic", "hermite"]
# The paper's settings run on these fixed meshes (elements per curve): 16, the mesh of the paper's
# runs so far, and finer ones, whose smaller bias may pay at the larger budgets. The tables and plots
# report the paper's method on its best fixed mesh for each budget (add_envelopes), and every mesh
# on its own in time-to-accuracy-errors.md.
PAPER_MESHES = {"constant": [16, 64], "linear": [16, 64, 256], "cubic": [16, 64, 256], "hermite": [16, 64]}
METHODS = []  # (label, family, basis, method string)
for basis in BASES:
    METHODS.append((basis, "default", basis, "basis=%s+estimator=%s+elements=auto+sampler=sobol+%s"
                    % (basis, DEFAULT_ESTIMATOR[basis], COMMON)))
for basis in BASES:
    for n in PAPER_MESHES[basis]:
        METHODS.append(("%s, paper, %d elements" % (basis, n), "paper", basis,
                        "basis=%s+estimator=lumped+elements=%d+sampler=random+%s" % (basis, n, COMMON)))
CLASSIC = ("basis=constant+estimator=lumped+elements=16+sampler=random+discontinuities=none+sampling=uniform"
           "+ray-width=0+transport=shooting+gather=none+control-variate=none")
METHODS.append(("classic", "classic", "constant", CLASSIC))
METHODS.append(("cubic, walks", "walk", "cubic", "basis=cubic+estimator=galerkin+elements=auto+sampler=sobol"
                "+discontinuities=auto+sampling=reconstructed+ray-width=0+transport=walk+gather=none+control-variate=none"))
for _name in [n for n in SCENES if n not in os.environ.get("TTA_SCENES", ",".join(SCENES)).split(",")]:
    del SCENES[_name]
QUICK_SCENES = ["penumbra", "round_occluder"]
QUICK_METHODS = ["linear", "cubic", "cubic, paper, 16 elements", "classic"]
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


# The paper's settings on the meshes finer than 16 elements are solved by a converge of their own,
# into <scene>/meshes/, so that each converge plot stays readable (at most 12 methods, each in a
# colour of its own) and the other methods' runs stay in <scene>/ as before.
MESHES_DIR = "meshes"


def run_dir(method):
    """The subdirectory of a scene's runs that holds a method's runs ('' or MESHES_DIR)."""
    return MESHES_DIR if method[1] == "paper" and "+elements=16+" not in method[3] else ""


def solve_scene(name, out, methods, budgets):
    scene, n = SCENES[name]
    os.makedirs(out, exist_ok=True)
    # Paths relative to the repository's top (the commands run there), so that the logs kept
    # beside the runs name no directory of the machine that made them.
    out = os.path.relpath(out, ROOT) if out.startswith(ROOT + os.sep) else out
    ref = os.path.join(out, "reference.json")
    run([FLATLAND, "reference", scene, "--elements", str(n), "--threads", THREADS, "--out", ref],
        os.path.join(out, "reference.txt"))
    for sub in ["", MESHES_DIR]:
        group = [m for m in methods if run_dir(m) == sub]
        if not group:
            continue
        assert len(group) <= 12, "a converge plot of more than 12 methods repeats its colours"
        where = os.path.join(out, sub) if sub else out
        os.makedirs(where, exist_ok=True)
        run([FLATLAND, "converge", scene, "--reference", ref, "--methods", ",".join(m[3] for m in group),
             "--budgets", ",".join(budgets), "--seeds", str(SEEDS), "--threads", THREADS,
             "--samples", "100", "--out", where], os.path.join(where, "converge.txt"))
        # converge's own plot (its methods, its legend) is kept under the converge name


def floor_of(out):
    """The reference's estimated error in the measure the runs are judged by (converge prints it)."""
    with open(os.path.join(out, "converge.txt")) as f:
        m = re.search(r"reference error \(estimated\) ([0-9.eE+-]+) relative L2", f.read())
    return float(m.group(1)) if m else 0.0


def load(out, methods, budgets):
    """{label: [(budget, median seconds, median error, min, max, median photons, errors by seed)]} of
    the runs of a scene's directory (its convergence.csv and, when there is one, that of MESHES_DIR).
    converge writes each method's budgets in order, seeds 1..S within each; the budget of a row is
    taken from its position (the rounds round the photons shot, so they do not name the budget)."""
    by_method = {m[3]: m[0] for m in methods}
    # Runs from before the control variate existed name their methods without "+control-variate=none",
    # and runs from before the final gather also without "+gather=none": that is what they did.
    by_method.update({m[3].replace("+control-variate=none", ""): m[0] for m in methods})
    by_method.update({m[3].replace("+gather=none+control-variate=none", ""): m[0] for m in methods})
    runs = {}
    paths = [os.path.join(out, "convergence.csv"), os.path.join(out, MESHES_DIR, "convergence.csv")]
    for path in [p for p in paths if os.path.exists(p)]:
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


def paper_label(basis, n):
    return "%s, paper, %d elements" % (basis, n)


def envelope_label(basis):
    return "%s, paper (best of %s)" % (basis, "/".join(str(n) for n in PAPER_MESHES[basis]))


def add_envelopes(med):
    """Adds to med, per basis, the paper's settings on their best fixed mesh for each budget: at each
    budget the row of the mesh (PAPER_MESHES) with the least median error (the coarser on a tie),
    with that mesh appended to the row. The choice is made with hindsight, after every mesh has run
    at every budget: generous to the paper."""
    for basis in BASES:
        meshes = [(n, med[paper_label(basis, n)]) for n in PAPER_MESHES[basis]]
        med[envelope_label(basis)] = [
            min((rows[i] + (n,) for n, rows in meshes), key=lambda r: (r[2], r[7]))
            for i in range(len(meshes[0][1]))]
    return med


def meshes_text():
    """The paper's meshes in words: '16, 64 or 256 elements per curve for linear and cubic, 16 or 64
    for constant and hermite'."""
    groups = {}
    for b in BASES:
        groups.setdefault(tuple(PAPER_MESHES[b]), []).append(b)
    return ", ".join("%s or %d%s for %s" % (", ".join(str(n) for n in m[:-1]), m[-1],
                                            " elements per curve" if i == 0 else "", " and ".join(bs))
                     for i, (m, bs) in enumerate(sorted(groups.items(), key=lambda g: -len(g[0]))))


def mesh_of(row):
    """The mesh a row of a paper envelope was chosen on; None for the row of a single method."""
    return row[7] if len(row) > 7 else None


def fmt_t(tk):
    t, kind = tk
    if kind == ">":
        return "–"
    s = "%.2g s" % t if t < 10 else "%.0f s" % t
    return "< " + s if kind == "<" else s


def fmt_e(e):
    return "%.2g %%" % (100 * e)


def fmt_e_iqr(row):
    """A row's median error in percent with its interquartile range over the seeds (spread.py), and
    the mesh of an envelope's row: '3.2 % [3.1–3.3 %] (64)'."""
    return spread.percent(list(row[6].values())) + (" (%d)" % mesh_of(row) if mesh_of(row) else "")


def median_text(cell):
    """The median of a table's cell: the text before its interquartile range ' [' or its ' ('."""
    return re.split(r" \(| \[", cell, maxsplit=1)[0]


def nice(name):
    return name.replace("_", " ")


def series(paper):
    """(label, family, basis) of the rows a table or plot reports, in order: the defaults, the paper's
    settings (paper: 'best' its best fixed mesh per budget, 'best+16' that and the 16-element setting
    below it, 'all' that and every mesh), classic and walks."""
    out = [(m[0], m[1], m[2]) for m in METHODS if m[1] == "default"]
    for basis in BASES:
        out.append((envelope_label(basis), "paper", basis))
        if paper != "best":
            out += [(paper_label(basis, n), "paper", basis) for n in PAPER_MESHES[basis] if paper == "all" or n == 16]
    return out + [(m[0], m[1], m[2]) for m in METHODS if m[1] in ("classic", "walk")]


def plot(out_png, scene, med, floor):
    """Median error against median time, one line per method (the paper's settings on their best
    fixed mesh per budget); legend below the axes."""
    dat = out_png[:-4] + ".dat"
    styles = {"default": (1, 7), "paper": (2, 6), "classic": (1, 5), "walk": (4, 9)}
    colours = {"constant": "#7f7f7f", "linear": "#1f77b4", "cubic": "#d62728", "hermite": "#2ca02c"}
    lines, i = [], 0
    plotted = series("best")
    with open(dat, "w") as f:
        for label, family, basis in plotted:
            if label not in med:
                continue
            f.write("# %s: budget seconds median_rel_l2 min max photons\n" % label)
            for r in med[label]:
                f.write("%g %.6g %.6g %.6g %.6g %.6g\n" % r[:6])
            f.write("\n\n")
            dt, pt = styles[family]
            colour = "#000000" if family == "classic" else ("#9467bd" if family == "walk" else colours[basis])
            estimator = {"galerkin": "Galerkin", "local": "local", "lumped": "lumped"}[DEFAULT_ESTIMATOR[basis]]
            title = {"default": "%s (defaults: %s, auto mesh, Sobol')" % (basis, estimator),
                     "paper": "%s, paper (lumped, best fixed mesh per budget of %s elements, random)"
                              % (basis, "/".join(str(n) for n in PAPER_MESHES[basis])),
                     "classic": "classic (constant, lumped, 16 elements, uniform origins, no events, random)",
                     "walk": "cubic, random walks (defaults)"}[family]
            lines.append("'%s' index %d using 2:3:4:5 with yerrorlines lw 2 dt %d pt %d ps 0.8 lc rgb '%s' title \"%s\" noenhanced"
                         % (os.path.basename(dat), i, dt, pt, colour, title))
            i += 1
    lines.append("0.01 with lines lc rgb '#444444' dt 2 lw 1 title 'targets: 1 % and 0.1 %'")
    lines.append("0.001 with lines lc rgb '#444444' dt 2 lw 1 notitle")
    smallest = min(r[3] for label, _, _ in plotted if label in med for r in med[label])
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


def tables(d, tdir, plots=True):
    """Writes the five tables to tdir from the runs under d, and with plots the figures beside the runs."""
    data, floors, checks = {}, {}, []
    for name in SCENES:
        out = os.path.join(d, name)
        data[name] = add_envelopes(load(out, METHODS, BUDGETS))
        floors[name] = floor_of(out)
        if plots:
            plot(os.path.join(d, name + ".png"), name, data[name], floors[name])
        checks.append(check_reference(name, data[name], floors[name]))
    best = meshes_text()

    lines = []
    w = lines.append
    w("Time to a relative L2 error of B - E of 1 %% and 0.1 %% (median over %d seeds; '–': not reached by 1e7"
      " photons), error at %s photons (the median [its interquartile range over the %d seeds: the first and"
      " third quartiles by Python's statistics.quantiles(method='inclusive'), for %d seeds the second smallest"
      " and the second largest error]), and cost per photon at 1e7 photons, %s thread(s). 'X, paper (best of"
      " ...)' is the paper's settings on the fixed mesh (%s) with the least median error"
      " at each budget, chosen with hindsight, after every mesh has run at every budget: generous to the"
      " paper. Its times to 1 %% and 0.1 %% are interpolated on those meshes' (median time, median error)"
      " points, its error at 1e6 photons names the mesh chosen there in parentheses, and its cost per"
      " photon is that of the mesh chosen at 1e7; 'X, paper, 16 elements' is the paper's settings on 16"
      " elements per curve at every budget:" % (SEEDS, "1e6", SEEDS, SEEDS, THREADS, best))
    w("")
    w("| scene | method | to 1 % | to 0.1 % | error at 1e6 photons | ns per photon |")
    w("|---|---|---|---|---|---|")
    for name, med in data.items():
        for label, family, basis in series("best+16"):
            if family == "walk":
                continue
            rows = med[label]
            at = [r for r in rows if r[0] == FIXED_BUDGET][0]
            w("| %s | %s | %s | %s | %s | %.0f |" % (nice(name), label, fmt_t(time_to(rows, 1e-2)),
                                                     fmt_t(time_to(rows, 1e-3)), fmt_e_iqr(at), cost_per_photon(rows)))
    w("")
    w("References (the check every comparison makes): " + "; ".join(c[1] for c in checks) + ".")
    write(tdir, "time-to-accuracy", lines)

    lines = []
    w = lines.append
    w("Median relative L2 error of B - E [its interquartile range over the %d seeds: the first and third"
      " quartiles by Python's statistics.quantiles(method='inclusive'), for %d seeds the second smallest and"
      " the second largest error] (median solve time) per photon budget. 'X, paper (best of ...)' is, at each"
      " budget, the paper's settings on the fixed mesh with the least median error, chosen with hindsight"
      " (generous to the paper), the mesh (elements per curve) named in parentheses before the time; the"
      " plots draw these rows for the paper's settings, and each mesh's own row follows them:" % (SEEDS, SEEDS))
    for name, med in data.items():
        w("")
        w("| %s | %s |" % (nice(name), " | ".join(BUDGETS)))
        w("|---|%s" % ("---|" * len(BUDGETS)))
        for label, _, _ in series("all"):
            w("| %s | %s |" % (label, " | ".join(
                "%s (%s%.2g s)" % (spread.cell(list(r[6].values())), "%d, " % mesh_of(r) if mesh_of(r) else "", r[1])
                for r in med[label])))
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
    # photons as the geometric mean over the scenes, and the cost per photon against linear's (the
    # paper's settings and classic against the paper's linear); the paper's settings on their best
    # fixed mesh per budget.
    lines = []
    w = lines.append
    w("| method | %s | error at 1e6 photons (geometric mean) | time per photon / linear's |"
      % " | ".join(nice(n) for n in data))
    w("|---|%s---|---|" % ("---|" * len(data)))
    for label, family, basis in series("best"):
        if family == "walk":
            continue
        cells = []
        for name, med in data.items():
            rows = med[label]
            cells.append("%s / %s" % (fmt_t(time_to(rows, 1e-2)), fmt_t(time_to(rows, 1e-3))))
        gm = math.exp(statistics.mean(math.log([r for r in med[label] if r[0] == FIXED_BUDGET][0][2])
                                      for med in data.values()))
        base = "linear" if family == "default" else envelope_label("linear")
        cost = statistics.median(cost_per_photon(med[label]) / cost_per_photon(med[base]) for med in data.values())
        w("| %s | %s | %s | %.2fx |" % ("**%s**" % label if label == envelope_label("cubic") else label,
                                        " | ".join(cells), fmt_e(gm), cost))
    write(tdir, "readme-answer", lines)
    write(tdir, "time-to-accuracy-findings", findings(data))
    return all(c[0] for c in checks)


def findings(data):
    """The table's answers as sentences, computed here so that no number in them is typed."""
    names = list(data)
    out = []
    w = out.append
    reach = {label: [n for n in names if time_to(data[n][label], 1e-3)[1] != ">"] for label in data[names[0]]}
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

    def listed(scenes):
        return ", ".join(nice(n) for n in scenes) if scenes else "none"

    sixteen = [paper_label(b, 16) for b in BASES] + ["classic"]
    bests = [envelope_label(b) for b in BASES] + ["classic"]
    stuck16 = [n for n in names if all(time_to(data[n][l], 1e-2)[1] == ">" for l in sixteen)]
    stuck = [n for n in names if all(time_to(data[n][l], 1e-2)[1] == ">" for l in bests)]
    w("- Scenes where no storage with the paper's lumped deposits (nor classic) reaches 1 %% by 1e7 photons: on 16"
      " fixed elements per curve, %s; on its best fixed mesh per budget (%s, chosen with hindsight), %s."
      % (listed(stuck16), meshes_text(), listed(stuck)))
    tenth = [(b, [n for n in names if time_to(data[n][envelope_label(b)], 1e-3)[1] != ">"]) for b in BASES]
    w("- On its best fixed mesh per budget the paper's settings reach 0.1 %% %s." % (
        "on no scene" if not any(sc for _, sc in tenth) else "; ".join(
            "%s on %s" % (b, listed(sc)) for b, sc in tenth if sc)))
    i6, i7 = BUDGETS.index([b for b in BUDGETS if float(b) == FIXED_BUDGET][0]), len(BUDGETS) - 1
    falls = [statistics.median(data[n][paper_label("cubic", m)][i6][2] / data[n][paper_label("cubic", m)][i7][2]
                               for n in names) for m in PAPER_MESHES["cubic"]]
    w("- From %s to %s photons the median error of cubic, paper falls by a factor of %s on %s elements per curve"
      " (medians over the scenes; noise alone would fall by %.1f, a mesh's bias not at all)." % (
          BUDGETS[i6], BUDGETS[i7], ", ".join("%.1f" % f for f in falls),
          ", ".join(str(m) for m in PAPER_MESHES["cubic"]), math.sqrt(float(BUDGETS[i7]) / float(BUDGETS[i6]))))
    w("- The best fixed mesh of cubic, paper at %s photons: %s." % (
        ", ".join(BUDGETS), "; ".join("%s %s" % (nice(n), "/".join(str(mesh_of(r))
                                                                   for r in data[n][envelope_label("cubic")]))
                                      for n in names)))
    w("- Cubic, paper at %s photons on its best fixed mesh against 16 elements: %s." % (
        BUDGETS[-1], ", ".join("%s %.2g %% (%d elements) against %.2g %%" % (
            nice(n), 100 * data[n][envelope_label("cubic")][-1][2], mesh_of(data[n][envelope_label("cubic")][-1]),
            100 * data[n][paper_label("cubic", 16)][-1][2]) for n in names)))
    gain = statistics.median(data[n][envelope_label("cubic")][-1][2] / data[n]["cubic"][-1][2] for n in names)
    gain16 = statistics.median(data[n][paper_label("cubic", 16)][-1][2] / data[n]["cubic"][-1][2] for n in names)
    w("- At %s photons the defaults' cubic error is %.0fx below the paper's method's on its best fixed mesh, %.0fx"
      " below it on 16 elements (medians over the scenes)." % (BUDGETS[-1], gain, gain16))
    return out


def write(tdir, name, lines):
    with open(os.path.join(tdir, name + ".md"), "w") as f:
        f.write("\n".join(lines) + "\n")


TABLES = ["time-to-accuracy", "time-to-accuracy-errors", "walks", "readme-answer", "time-to-accuracy-findings"]
NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


def committed_text(path):
    """A committed table without the line docs/reproduce.sh heads it with (commit, command, time)."""
    text = open(path).read()
    return text.split("\n", 2)[2] if text.startswith("*Made by") else text


def compare_with_runs(d, tdir):
    """Every committed table against the same table made again from the committed runs (d/<scene>/
    convergence.csv and converge.txt, no solve): the same script on the same numbers writes the same
    text, times included, so any difference is a number typed or edited in the table, or a table the
    script would no longer write. Prints one line per table."""
    made = tempfile.mkdtemp(prefix="flatland-tables-")
    try:
        tables(d, made, plots=False)
        bad = 0
        for name in TABLES:
            if not os.path.exists(os.path.join(tdir, name + ".md")):
                bad += 1
                print("  %s.md: DIFFERS: there is no committed table" % name)
                continue
            old = committed_text(os.path.join(tdir, name + ".md"))
            new = open(os.path.join(made, name + ".md")).read()
            if old == new:
                print("  %s.md: the same text as made again from the committed runs (%d numbers)"
                      % (name, len(NUMBER.findall(new))))
                continue
            bad += 1
            print("  %s.md: DIFFERS from the table made again from the committed runs:" % name)
            a, b = old.split("\n"), new.split("\n")
            first = open(os.path.join(tdir, name + ".md")).read().count("\n") - old.count("\n") + 1
            shown = 0
            for k, (x, y) in enumerate(zip(a, b)):
                if x != y and shown < 5:
                    print("    line %d: %r, made again: %r" % (first + k, x, y))
                    shown += 1
            if len(a) != len(b):
                print("    it has %d lines, made again %d" % (len(a), len(b)))
        return bad == 0
    finally:
        shutil.rmtree(made)


def markdown_tables(path):
    """Every Markdown table of a committed table file: [(header cells, [row cells])]."""
    return parse_tables(committed_text(path))[0]


def cell(path, first_header, key, column):
    """The cell in column `column` of the row whose first cells are `key`, in the table whose first
    header cell is first_header (None: any table with that column); None when there is none."""
    for header, rows in markdown_tables(path):
        if (first_header is not None and header[0] != first_header) or column not in header:
            continue
        for r in rows:
            if tuple(r[:len(key)]) == key:
                return r[header.index(column)]
    return None


def printed(text, digits):
    """(value, half a unit of its last significant digit) of a number a table prints with `digits`
    significant digits ('%g' drops trailing zeros: '0.1 %' of "%.2g %%" is 0.10 %, that is 0.0010)."""
    scale = 0.01 if text.strip().endswith("%") else 1.0
    v = float(NUMBER.search(text).group(0)) * scale
    return v, 0.5 * 10.0 ** (math.floor(math.log10(v)) - digits + 1)


def quick_cells(tdir, name, label, budget):
    """The numbers of the Markdown tables that state this run's median error: (table, its cell's
    median (median_text) or None, the text the table's script writes for a median, significant
    digits)."""
    column = [b for b in BUDGETS if float(b) == budget][0]
    def median(text):  # a cell's median: without its interquartile range ' [...]' and its ' (...)'
        return text and median_text(text)

    errors = cell(os.path.join(tdir, "time-to-accuracy-errors.md"), nice(name), (label,), column)
    out = [("time-to-accuracy-errors.md", median(errors), lambda e: "%.3g" % e, 3)]
    if budget == FIXED_BUDGET:
        out.append(("time-to-accuracy.md", median(cell(os.path.join(tdir, "time-to-accuracy.md"), None,
                                                       (nice(name), label), "error at 1e6 photons")), fmt_e, 2))
        if label == "cubic":
            out.append(("walks.md", median(cell(os.path.join(tdir, "walks.md"), None, (nice(name), "shooting"),
                                                "error at 1e6")), fmt_e, 2))
    return out


def tolerance(errors):
    """How far, as |log(quick median / committed median)|, the median of a changed program may lie from
    the committed one: 3 standard errors of the difference of two medians of len(errors) seeds, the
    standard error of each 1.2533 s / sqrt(n) with s the standard deviation of the committed seeds'
    log errors (the median of n draws is that much noisier than their mean), plus 0.02 for medians
    whose seeds agree to a few per mille (a bias larger than the noise: the spread of five seeds
    says less there). With 5 seeds that is 2.38 s + 0.02: in the runs made at da5f3af it allows at
    most a factor 3.2 (round occluder, cubic, 1e5, where one outlying seed makes s = 0.49), where
    the former 3 s + 0.05 allowed 4.5, and typically 1.3 to 1.6."""
    n = len(errors)
    s = statistics.stdev(math.log(e) for e in errors)
    return 3 * math.sqrt(2) * 1.2533 * s / math.sqrt(n) + 0.02, s


def compare_quick(d, scratch, tdir):
    """Each quick run against the committed run of the same scene, method, budget and seed, and its
    median against the numbers of the Markdown tables in tdir that state it. The program gives the
    same bits for a seed on any machine and thread count: where every seed gives the committed
    bits, each table's number must be the very text the script writes for the median. Where they
    differ (a change that draws other random numbers but solves the same problem), the number must
    agree within tolerance() of the median, plus half a unit of the number's last significant digit.
    Prints one line per run: how its seeds and each table's number agreed."""
    bad = 0
    methods = [m for m in METHODS if m[0] in QUICK_METHODS]
    for name in QUICK_SCENES:
        full = load(os.path.join(d, name), METHODS, BUDGETS)
        quick = load(os.path.join(scratch, name), methods, QUICK_BUDGETS)
        for label in QUICK_METHODS:
            for q in quick[label]:
                f = [r for r in full[label] if r[0] == q[0]][0]
                same = q[6] == f[6]
                differ = sum(q[6].get(seed) != e for seed, e in f[6].items())
                head = "  %-15s %-25s %-6g " % (name, label, q[0])
                parts = []
                if same:
                    head += "%d seeds: the committed bits; median %.4g:" % (len(f[6]), q[2])
                    for table, text, fmt, _ in quick_cells(tdir, name, label, q[0]):
                        ok = text == fmt(q[2])
                        bad += not ok
                        parts.append("%s has no such number: DISAGREES" % table if text is None else "%s %s %s" % (
                            table, text, "the same text" if ok else "DISAGREES (the median is written %s)" % fmt(q[2])))
                else:
                    tol, s = tolerance(list(f[6].values()))
                    head += "%d of %d seeds differ from the committed bits; median %.4g, tolerance %.3f (seeds' sd %.3f):" % (
                        differ, len(f[6]), q[2], tol, s)
                    for table, text, fmt, digits in quick_cells(tdir, name, label, q[0]):
                        if text is None:
                            bad += 1
                            parts.append("%s has no such number: DISAGREES" % table)
                            continue
                        v, half = printed(text, digits)
                        dev, allowed = abs(math.log(q[2] / v)), tol + math.log1p(half / v)
                        ok = dev <= allowed
                        bad += not ok
                        parts.append("%s %s |log ratio| %.3f of %.3f %s" % (table, text, dev, allowed,
                                                                           "within" if ok else "DISAGREES"))
                print(head + " " + "; ".join(parts))
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
        print("the tables of %s against the same tables made again from the committed runs:" % os.path.relpath(a.tables, ROOT))
        made = compare_with_runs(HERE, a.tables)
        print("each quick run against the committed runs and the numbers of the tables that state its median:")
        ok = compare_quick(HERE, scratch, a.tables)
        if made and ok:
            shutil.rmtree(scratch)
        else:
            print("the quick runs are kept in %s" % scratch)
        print("time to accuracy, quick: %s" % ("agrees with the committed runs and tables" if made and ok else "DISAGREES"))
        sys.exit(0 if made and ok else 1)
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

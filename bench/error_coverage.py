#!/usr/bin/env python3
"""Coverage and sharpness of the estimated error (docs/experiments-error-and-optics.md,
"The estimated error").

For each scene: a reference (flatland reference), then `flatland converge` over methods, budgets
and seeds, whose table holds each run's true error against the reference (rel_*) and the solver's
own estimated bound (est_*). Per scene, method and budget it reports how many runs the bound
covered (true <= estimate) and the median of estimate / true, in L1, L2 and Linf, as a Markdown
table on stdout and DIR/coverage.md.

  bench/error_coverage.py --out /tmp/coverage [--flatland build/flatland] [--seeds 40]
"""
import argparse
import re
import csv
import os
import statistics
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "figures"))
import spread  # noqa: E402 (after the path it needs)

# name -> (scene, elements of its reference): the reference must be 10x more accurate than the most
# accurate method it judges (the round occluder's gathered answer is within 5e-5).
SCENES = {
    "penumbra": ("scenes2d/penumbra.json", 1600),
    "round occluder": ("scenes2d/tests/reference_round_occluder.json", 4800),
    "ring profile": ("scenes2d/tests/reference_ring_profile.json", 1600),
    "furnace rho 0.9": ("scenes2d/experiments/enclosure_rho0.9.json", 1600),
    "row of rooms": ("scenes2d/row_of_rooms.json", 1600),
    "office": ("scenes2d/interreflection/office.json", 1600),
    "window room": ("scenes2d/interreflection/window_room.json", 1600),
}
# Measured unless --scenes names others: the row of rooms is there for importance's methods
# (e.g. --scenes "row of rooms" --methods cubic,cubic+importance=desk), the office and the window
# room (rooms of strong interreflection) for the default's methods.
DEFAULT_SCENES = "penumbra,round occluder,ring profile,furnace rho 0.9"
METHODS = ("cubic,linear,constant,hermite,cubic+sampler=random,cubic+transport=walk,cubic+elements=64,"
           "cubic+gather=samples,cubic+replicate-layout=blocks,hermite+replicate-layout=blocks")
# Relative errors below this are round-off: a final gather of direct light alone is exact, and
# neither its error nor its bound then says anything.
ROUND_OFF = 1e-12


# Every setting a method does not name is pinned to the defaults of the program measured (cubic,
# Galerkin for B-splines and local for Hermite, storage that follows the photons, reconstructed
# origins, direct-light events, Sobol' points, point rays, shooting), so a change of the program's
# defaults does not change what this measures.
PINNED = {"basis": "cubic", "elements": "auto", "sampling": "reconstructed", "discontinuities": "auto",
          "sampler": "sobol", "ray-width": "0", "transport": "shooting", "gather": "none",
          "control-variate": "none", "replicate-layout": "independent"}


def pinned(method):
    """The method's settings with every key it leaves out filled in: 'linear' or 'cubic+sampler=random'."""
    named = dict(p.split("=", 1) if "=" in p else ("basis", p) for p in method.split("+"))
    full = dict(PINNED, **named)
    full.setdefault("estimator", "local" if full["basis"] == "hermite" else "galerkin")
    return "+".join(k + "=" + v for k, v in full.items())


def run(command):
    """Seconds the command took and what it printed."""
    started = time.time()
    done = subprocess.run(command, check=True, stdout=subprocess.PIPE, text=True)
    return time.time() - started, done.stdout


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True)
    parser.add_argument("--flatland", default=os.environ.get("FLATLAND", "build/flatland"))
    parser.add_argument("--seeds", type=int, default=40)
    parser.add_argument("--budgets", default="1e5,1e6")
    parser.add_argument("--methods", default=METHODS)
    parser.add_argument("--scenes", default=DEFAULT_SCENES)
    parser.add_argument("--threads", default="2")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    rows, checks = [], []
    for name in args.scenes.split(","):
        scene, elements = SCENES[name]
        tag = name.replace(" ", "_").replace(".", "")
        reference = os.path.join(args.out, tag + "_reference.json")
        if not os.path.exists(reference):
            run([args.flatland, "reference", scene, "--elements", str(elements), "--out", reference, "--samples", "100",
                 "--quiet"])
        directory = os.path.join(args.out, tag)
        labels = {pinned(m): m for m in args.methods.split(",")}
        seconds, printed = run([args.flatland, "converge", scene, "--reference", reference, "--methods", ",".join(labels),
                       "--budgets", args.budgets, "--seeds", str(args.seeds), "--samples", "100",
                       "--threads", args.threads, "--out", directory])
        print(f"{name}: converge took {seconds:.0f} s", file=sys.stderr)
        runs = {}
        with open(os.path.join(directory, "convergence.csv")) as table:
            for row in csv.DictReader(table):
                budget = min(args.budgets.split(","), key=lambda b: abs(float(b) - float(row["photons"])))
                runs.setdefault((labels[row["method"]], budget), []).append(row)
        # The reference must be 10x more accurate than the smallest median error it judges.
        floor = float(re.search(r"reference error \(estimated\) ([0-9.eE+-]+) relative L2", printed).group(1))
        # (An answer exact to round-off judges nothing: the reference is exact there too.)
        judged = [m for m in (statistics.median(float(r["rel_l2"]) for r in group) for group in runs.values())
                  if m >= ROUND_OFF]
        if judged:
            smallest = min(judged)
            checks.append(f"{name}: {floor:.2g} against {smallest:.2g}, "
                          + ("good enough" if 10 * floor <= smallest else "NOT 10x below"))
        else:
            checks.append(f"{name}: every method exact to round-off")
        for (method, budget), group in runs.items():
            entry = {"scene": name, "method": method, "budget": budget, "runs": len(group)}
            for norm in ("l1", "l2", "linf"):
                true = [float(r["rel_" + norm]) for r in group]
                est = [float(r["est_" + norm]) for r in group]
                entry["covered_" + norm] = sum(e >= t for e, t in zip(est, true))
                ratios = [e / t for e, t in zip(est, true) if t > 0]
                entry["ratios_" + norm] = ratios
                entry["true_" + norm] = true
            rows.append(entry)
    lines = ["Runs whose estimate covers the true error (true <= estimate) per norm; estimate / true and the "
             "true L1 error, each the %s:" % spread.caption(args.seeds, "runs"), "",
             "| scene | method | photons | runs | covered L1 | L2 | Linf | est/true L1 | L2 | Linf "
             "| true L1 |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    def ratio(values):
        return spread.cell(values, lambda v: "%.2f" % v) if values else "nan"

    for e in rows:
        if statistics.median(e["true_l1"]) < ROUND_OFF:
            lines.append(f"| {e['scene']} | {e['method']} | {e['budget']} | {e['runs']} | exact | (round-off) | | | | "
                         f"| {spread.cell(e['true_l1'], lambda v: '%.2e' % v)} |")
            continue
        lines.append(f"| {e['scene']} | {e['method']} | {e['budget']} | {e['runs']} | {e['covered_l1']} | "
                     f"{e['covered_l2']} | {e['covered_linf']} | {ratio(e['ratios_l1'])} | {ratio(e['ratios_l2'])} | "
                     f"{ratio(e['ratios_linf'])} | {spread.cell(e['true_l1'], lambda v: '%.2e' % v)} |")
    lines += ["", "References (relative L2 error of B - E, estimated, against the smallest median error judged): "
              + "; ".join(checks) + "."]
    text = "\n".join(lines) + "\n"
    with open(os.path.join(args.out, "coverage.md"), "w") as out:
        out.write(text)
    print(text)
    if any("NOT" in c for c in checks):
        sys.exit("a reference is not 10x more accurate than the errors it judges")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The figure of docs/experiments-error-and-optics.md, "The estimated error": median true and
estimated relative L1 error of B - E against photons, per method, on one scene (flatland converge,
then gnuplot).

  bench/estimated_error_figure.py --out docs/figures/estimated_error [--flatland build/flatland]
"""
import argparse
import sys
import re
import csv
import os
import statistics
import subprocess


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True)
    parser.add_argument("--flatland", default=os.environ.get("FLATLAND", "build/flatland"))
    parser.add_argument("--scene", default="scenes2d/tests/reference_round_occluder.json")
    parser.add_argument("--methods", default="constant,linear,cubic,hermite")
    parser.add_argument("--budgets", default="1e4,3e4,1e5,3e5,1e6,3e6")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--replot", action="store_true", help="draw again from DIR/runs/convergence.csv")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    work = os.path.join(args.out, "runs")
    # Every setting pinned to the defaults of the program measured but the basis (the figure's
    # subject), so a change of defaults does not change it; hermite takes the local estimator, the
    # others Galerkin, as the defaults do.
    full = ["basis=%s+estimator=%s+elements=auto+sampling=reconstructed+discontinuities=auto+sampler=sobol"
            "+ray-width=0+transport=shooting+gather=none" % (b, "local" if b == "hermite" else "galerkin")
            for b in args.methods.split(",")]
    if not args.replot:
        os.makedirs(work, exist_ok=True)
        reference = os.path.join(work, "reference.json")
        subprocess.run([args.flatland, "reference", args.scene, "--elements", "1600", "--threads", "2", "--quiet",
                        "--out", reference], check=True)
        done = subprocess.run([args.flatland, "converge", args.scene, "--reference", reference, "--methods",
                               ",".join(full), "--budgets", args.budgets, "--seeds", str(args.seeds), "--tolerance",
                               "1e-3", "--threads", "2", "--out", work], check=True, stdout=subprocess.PIPE, text=True)
        with open(os.path.join(work, "converge.txt"), "w") as out:
            out.write(done.stdout)
    with open(os.path.join(work, "convergence.csv")) as table:
        rows = list(csv.DictReader(table))
    methods = args.methods.split(",")
    budgets = args.budgets.split(",")
    per = args.seeds
    data = []
    for m, method in enumerate(methods):
        block = []
        for b, _ in enumerate(budgets):
            group = rows[(m * len(budgets) + b) * per:(m * len(budgets) + b + 1) * per]
            block.append("%g %g %g" % (statistics.median(float(r["photons"]) for r in group),
                                       statistics.median(float(r["rel_l1"]) for r in group),
                                       statistics.median(float(r["est_l1"]) for r in group)))
        data.append("\n".join(block))
    with open(os.path.join(args.out, "estimated_error.dat"), "w") as out:
        out.write("\n\n\n".join(data) + "\n")
    # The reference must be 10x more accurate than the smallest median error it judges (converge
    # printed its estimate, relative L2 of B - E; the figure's errors are L1, of the same size).
    with open(os.path.join(work, "converge.txt")) as printed:
        floor = float(re.search(r"reference error \(estimated\) ([0-9.eE+-]+)", printed.read()).group(1))
    smallest = min(float(line.split()[1]) for block in data for line in block.split("\n"))
    check = "reference error %.2g against the smallest median error %.2g: %s" % (
        floor, smallest, "good enough" if 10 * floor <= smallest else "NOT 10x below")
    name = os.path.splitext(os.path.basename(args.scene))[0]
    plots = []
    for m, method in enumerate(methods):
        plots.append(f"'estimated_error.dat' index {m} using 1:2 with linespoints lw 2 lc {m + 1} pt 7 "
                     f"title '{method}'")
        plots.append(f"'estimated_error.dat' index {m} using 1:3 with linespoints dt 2 lw 2 lc {m + 1} pt 6 notitle")
    plots.append("NaN with linespoints lw 2 lc rgb 'gray30' pt 7 title 'true error (solid)'")
    plots.append("NaN with linespoints dt 2 lw 2 lc rgb 'gray30' pt 6 title 'estimated bound, 95 % (dashed)'")
    script = f"""set terminal pngcairo size 1100,640
set output 'estimated_error.png'
set logscale xy
set grid
set key outside right
set xlabel 'photons'
set ylabel 'relative L1 error of B - E'
set title "{name}: estimated bound and true error\\nmedian over {args.seeds} seeds; default settings but the basis" noenhanced
plot {", ".join(plots)}
"""
    with open(os.path.join(args.out, "estimated_error.gp"), "w") as out:
        out.write(script)
    subprocess.run(["gnuplot", "estimated_error.gp"], cwd=args.out, check=True)
    print(os.path.join(args.out, "estimated_error.png") + ": " + check)
    if "NOT" in check:
        sys.exit("the reference is not 10x more accurate than the errors it judges")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""The figure of docs/experiments.md, "The estimated error": median true and estimated relative L1
error of B - E against photons, per method, on one scene (flatland converge, then gnuplot).

  bench/estimated_error_figure.py --out docs/figures/estimated_error [--flatland build/flatland]
"""
import argparse
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
    if not args.replot:
        subprocess.run([args.flatland, "converge", args.scene, "--methods", args.methods, "--budgets", args.budgets,
                        "--seeds", str(args.seeds), "--tolerance", "1e-3", "--threads", "2", "--out", work],
                       check=True, stdout=subprocess.DEVNULL)
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
    name = os.path.splitext(os.path.basename(args.scene))[0]
    plots = []
    for m, method in enumerate(methods):
        plots.append(f"'estimated_error.dat' index {m} using 1:2 with linespoints lw 2 lc {m + 1} pt 7 "
                     f"title '{method}'")
        plots.append(f"'estimated_error.dat' index {m} using 1:3 with linespoints dt 2 lw 2 lc {m + 1} pt 6 notitle")
    plots.append("NaN with linespoints lw 2 lc rgb 'gray30' pt 7 title 'true error (solid)'")
    plots.append("NaN with linespoints dt 2 lw 2 lc rgb 'gray30' pt 6 title 'estimated bound, 95 % (dashed)'")
    script = f"""set terminal pngcairo size 900,640
set output 'estimated_error.png'
set logscale xy
set grid
set key bottom left box opaque
set xlabel 'photons'
set ylabel 'relative L1 error of B - E'
set title "{name}: estimated bound and true error\\nmedian over {args.seeds} seeds; default settings but the basis" noenhanced
plot {", ".join(plots)}
"""
    with open(os.path.join(args.out, "estimated_error.gp"), "w") as out:
        out.write(script)
    subprocess.run(["gnuplot", "estimated_error.gp"], cwd=args.out, check=True)
    print(os.path.join(args.out, "estimated_error.png"))


if __name__ == "__main__":
    main()

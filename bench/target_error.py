#!/usr/bin/env python3
"""What `--target-error` spends and delivers (docs/experiments-error-and-optics.md,
"Solving to a target").

Per scene: `flatland solve --target-error T --photons CAP` over seeds, each compared with a
reference (the true error) and its photons counted; and `flatland converge` of the default method
over a grid of fixed budgets (factors of sqrt 2) and the same seeds, to find the smallest fixed
budget whose median true error, and whose median estimated error, is at most T. Prints a Markdown
table (also DIR/target.md).

  bench/target_error.py --out /tmp/target [--flatland build/flatland] [--target 2e-3] [--seeds 20]
"""
import argparse
import csv
import json
import re
import os
import statistics
import subprocess
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "docs", "figures"))
import spread  # noqa: E402 (after the path it needs)

SCENES = {
    "penumbra": "scenes2d/penumbra.json",
    "round occluder": "scenes2d/tests/reference_round_occluder.json",
    "ring profile": "scenes2d/tests/reference_ring_profile.json",
    "furnace rho 0.9": "scenes2d/experiments/enclosure_rho0.9.json",
}


# Every setting pinned to the defaults of the program measured, so a change of defaults does not
# change what this measures: the default method (cubic storage, Galerkin, storage that follows the
# photons, reconstructed origins, direct-light events, Sobol' points, point rays).
PINNED_ARGS = ["--basis", "cubic", "--estimator", "galerkin", "--elements", "auto", "--sampling", "reconstructed",
               "--discontinuities", "auto", "--sampler", "sobol", "--ray-width", "0", "--transport", "shooting", "--gather", "none", "--control-variate", "none"]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True)
    parser.add_argument("--flatland", default=os.environ.get("FLATLAND", "build/flatland"))
    parser.add_argument("--target", type=float, default=2e-3)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--scenes", default=",".join(SCENES))
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    lines = [f"Photons spent and true L1 error of `--target-error` solves, each the {spread.caption(args.seeds)}:", "",
             f"| scene | target | runs | true error <= 1.2 target | photons spent | true L1 | "
             f"smallest fixed budget: true <= target | estimate <= target | photons / those |",
             "|---|---|---|---|---|---|---|---|---|"]
    checks = []
    for name in args.scenes.split(","):
        scene = SCENES[name]
        tag = name.replace(" ", "_").replace(".", "")
        reference = os.path.join(args.out, tag + "_reference.json")
        if not os.path.exists(reference):
            subprocess.run([args.flatland, "reference", scene, "--elements", "1600", "--out", reference, "--quiet"],
                           check=True)
        photons, errors = [], []
        for seed in range(1, args.seeds + 1):
            out = os.path.join(args.out, f"{tag}_{seed}.json")
            subprocess.run([args.flatland, "solve", scene, "--photons", "1e9", "--target-error", str(args.target),
                            "--seed", str(seed), "--threads", "2", "--out", out, "--quiet"] + PINNED_ARGS, check=True)
            compared = subprocess.run([args.flatland, "compare", out, reference, "--json"], check=True,
                                      capture_output=True, text=True)
            errors.append(json.loads(compared.stdout)["scene"]["l1"])
            with open(out) as result:
                photons.append(json.load(result)["stats"]["photons"])
            os.remove(out)
        grid = [int(1e4 * 2 ** (k / 2)) for k in range(0, 27)]
        top = max(photons)
        grid = [b for b in grid if b <= 2 * top]
        directory = os.path.join(args.out, tag)
        converged = subprocess.run([args.flatland, "converge", scene, "--reference", reference, "--methods",
                        "basis=cubic+estimator=galerkin+elements=auto+sampling=reconstructed+discontinuities=auto"
                        "+sampler=sobol+ray-width=0+transport=shooting+gather=none+control-variate=none",
                        "--budgets", ",".join(map(str, grid)), "--seeds", str(args.seeds), "--tolerance", "1e-3",
                        "--threads", "2", "--out", directory], check=True, stdout=subprocess.PIPE, text=True)
        with open(os.path.join(directory, "convergence.csv")) as table:
            rows = list(csv.DictReader(table))  # method, then budget, then seed order
        per = len(rows) // len(grid)
        true_ok = est_ok = None
        for i, budget in enumerate(grid):
            group = rows[i * per:(i + 1) * per]
            if true_ok is None and statistics.median(float(r["rel_l1"]) for r in group) <= args.target:
                true_ok = budget
            if est_ok is None and statistics.median(float(r["est_l1"]) for r in group) <= args.target:
                est_ok = budget
        # The reference must be 10x more accurate than the smallest median error judged (converge
        # prints its estimate in the same measure, relative L2 of B - E; the targets are in L1).
        floor = float(re.search(r"reference error \(estimated\) ([0-9.eE+-]+)", converged.stdout).group(1))
        smallest = min(statistics.median(errors), min(statistics.median(float(r["rel_l1"]) for r in rows[i * per:(i + 1) * per])
                                                        for i in range(len(grid))))
        checks.append(f"{name} {floor:.2g} against {smallest:.2g}: " + ("good enough" if 10 * floor <= smallest
                                                                          else "NOT 10x below"))
        used = statistics.median(photons)
        within = sum(e <= 1.2 * args.target for e in errors)
        lines.append(f"| {name} | {args.target:g} | {args.seeds} | {within} | {spread.cell(photons)} | "
                     f"{spread.cell(errors, lambda v: '%.2e' % v)} | {true_ok or '> grid':} | {est_ok or '> grid'} | "
                     f"{used / true_ok if true_ok else float('nan'):.2f} / {used / est_ok if est_ok else float('nan'):.2f} |")
        print(lines[-1], file=sys.stderr)
    lines += ["", "References (relative L2 error of B - E, estimated, against the smallest median error judged): "
              + "; ".join(checks) + "."]
    text = "\n".join(lines) + "\n"
    with open(os.path.join(args.out, "target.md"), "w") as out:
        out.write(text)
    print(text)
    if any("NOT" in c for c in checks):
        sys.exit("a reference is not 10x more accurate than the errors it judges")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""A parameter study with the flatland module (docs/python.md): the error of the reflected light B - E
on the penumbra scene against the photon budget, for each storage basis, with pseudo-random and with
Sobol' numbers, 3 seeds each. Writes parameter_study.csv and parameter_study.png (matplotlib) into the
directory given (default: this one). About 7 s on one core.

    PYTHONPATH=build/python python3 docs/examples/parameter_study.py docs/examples
"""
import csv
import os
import statistics
import sys

import flatland

out = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
scene = flatland.Scene.load("scenes2d/penumbra.json")
reference = flatland.reference(scene)  # the deterministic reference solution (flatland reference)

rows = []
for sampler in ["random", "sobol"]:
    for basis in ["constant", "linear", "cubic"]:
        for photons in [10_000, 100_000, 1_000_000]:
            for seed in [1, 2, 3]:
                result = flatland.solve(scene, photons=photons, seed=seed, basis=basis, sampler=sampler, threads=1)
                errors = flatland.compare(result, reference)  # B - E, relative L2 over the scene
                rows.append({"sampler": sampler, "basis": basis, "photons": photons, "seed": seed,
                             "seconds": result.stats["seconds"], "rel_l2": errors["scene"]["l2"]})
        print(f"{sampler:6s} {basis:8s} done", file=sys.stderr)

with open(os.path.join(out, "parameter_study.csv"), "w", newline="") as f:
    writer = csv.DictWriter(f, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

fig, ax = plt.subplots(figsize=(6.4, 4.2))
for sampler, style in [("random", "--"), ("sobol", "-")]:
    for basis, colour in [("constant", "tab:gray"), ("linear", "tab:blue"), ("cubic", "tab:orange")]:
        budgets = sorted({r["photons"] for r in rows})
        medians = [statistics.median(r["rel_l2"] for r in rows
                                     if r["sampler"] == sampler and r["basis"] == basis and r["photons"] == n)
                   for n in budgets]
        ax.loglog(budgets, medians, style, color=colour, marker="o", label=f"{basis}, {sampler}")
ax.set_xlabel("photons")
ax.set_ylabel("relative L2 error of B - E (median of 3 seeds)")
ax.set_title("penumbra scene: storage basis and sampler")
ax.grid(True, which="both", alpha=0.3)
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(os.path.join(out, "parameter_study.png"), dpi=110)
print("wrote parameter_study.csv and parameter_study.png in", out, file=sys.stderr)

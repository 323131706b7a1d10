#!/usr/bin/env python3
"""What each ingredient buys: from classic Monte Carlo radiosity to Flatland's defaults, one setting
at a time, at a fixed budget of 1e6 photons on the five scenes of the time-to-accuracy experiment
(their references, made by run.py, must exist).

    docs/figures/time_to_accuracy/ingredients.py [--tables DIR]

Writes TABLES/ingredients.md: per step, the median relative L2 error of B - E over SEEDS seeds on
every scene with its interquartile range, the geometric mean of the scenes' errors against the step before, and the median solve
time. Environment: FLATLAND (default build/flatland), THREADS (default 2)."""
import argparse, csv, math, os, statistics, subprocess, sys, tempfile

import run as tta

sys.path.insert(0, os.path.join(tta.ROOT, "docs", "figures"))
import spread  # noqa: E402 (after the path it needs)

SEEDS = 5
BUDGET = "1e6"
STEPS = [  # (what the step adds, the complete settings after it)
    ("classic: constant storage on 16 elements per curve, lumped deposits, origins uniform in arc length, "
     "no discontinuities, pseudo-random numbers",
     "basis=constant+estimator=lumped+elements=16+sampling=uniform+discontinuities=none+sampler=random"),
    ("+ cubic storage",
     "basis=cubic+estimator=lumped+elements=16+sampling=uniform+discontinuities=none+sampler=random"),
    ("+ photon origins drawn from the reconstruction",
     "basis=cubic+estimator=lumped+elements=16+sampling=reconstructed+discontinuities=none+sampler=random"),
    ("+ selected discontinuities (direct-light events): **the paper's method**",
     "basis=cubic+estimator=lumped+elements=16+sampling=reconstructed+discontinuities=auto+sampler=random"),
    ("+ Galerkin estimator instead of lumped deposits",
     "basis=cubic+estimator=galerkin+elements=16+sampling=reconstructed+discontinuities=auto+sampler=random"),
    ("+ storage mesh that follows the photons (auto)",
     "basis=cubic+estimator=galerkin+elements=auto+sampling=reconstructed+discontinuities=auto+sampler=random"),
    ("+ scrambled Sobol' points: Flatland's defaults",
     "basis=cubic+estimator=galerkin+elements=auto+sampling=reconstructed+discontinuities=auto+sampler=sobol"),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--tables", default=os.path.join(tta.ROOT, "docs", "tables"))
    a = ap.parse_args()
    methods = [s + "+ray-width=0+transport=shooting+gather=none+control-variate=none" for _, s in STEPS]
    err, spreads, secs, checks = {}, {}, {}, []
    for name, (scene, _) in tta.SCENES.items():
        ref = os.path.join(tta.HERE, name, "reference.json")
        if not os.path.exists(ref):
            sys.exit("%s is missing: run docs/figures/time_to_accuracy/run.py first" % ref)
        out = tempfile.mkdtemp(prefix="flatland-ingredients-")
        tta.run([tta.FLATLAND, "converge", scene, "--reference", ref, "--methods", ",".join(methods), "--budgets",
                 BUDGET, "--seeds", str(SEEDS), "--threads", tta.THREADS, "--samples", "100", "--out", out],
                os.path.join(out, "converge.txt"))
        floor = tta.floor_of(out)
        with open(os.path.join(out, "convergence.csv")) as f:
            rows = list(csv.DictReader(f))
        for i, m in enumerate(methods):
            es = [float(r["rel_l2"]) for r in rows if r["method"] == m]
            err[name, i] = statistics.median(es)
            spreads[name, i] = spread.percent(es)
            secs[name, i] = statistics.median(float(r["seconds"]) for r in rows if r["method"] == m)
        smallest = min(err[name, i] for i in range(len(methods)))
        ratio = smallest / floor if floor > 0 else float("inf")
        checks.append("%s: reference error %.2g against %.2g (%s), %s" % (
            tta.nice(name), floor, smallest, "%.0fx" % ratio if ratio < 1e4 else "more than 1e4x",
            "good enough" if floor * 10 <= smallest else "NOT 10x below"))
    names = list(tta.SCENES)
    lines = ["Relative L2 error of B - E at %s photons, the %s, %s thread(s); 'gain': the "
             "geometric mean over the scenes of the median error before the step / after it; time: median solve "
             "seconds, geometric mean over the scenes:" % (BUDGET, spread.caption(SEEDS), tta.THREADS), "",
             "| step | %s | gain | time |" % " | ".join(tta.nice(n) for n in names),
             "|---|%s---|---|" % ("---|" * len(names))]
    for i, (what, _) in enumerate(STEPS):
        gain = "" if i == 0 else "%.2fx" % math.exp(statistics.mean(
            math.log(err[n, i - 1] / err[n, i]) for n in names))
        t = math.exp(statistics.mean(math.log(secs[n, i]) for n in names))
        lines.append("| %s | %s | %s | %.2g s |" % (what, " | ".join(spreads[n, i] for n in names), gain, t))
    lines += ["", "Settings of each step (with ray-width=0, transport=shooting): " +
              "; ".join("%d. `%s`" % (i, s) for i, (_, s) in enumerate(STEPS)) + ".",
              "", "References: " + "; ".join(checks) + "."]
    os.makedirs(a.tables, exist_ok=True)
    tta.write(a.tables, "ingredients", lines)
    if any("NOT" in c for c in checks):
        sys.exit("a reference is not 10x more accurate than the errors it judges")


if __name__ == "__main__":
    main()

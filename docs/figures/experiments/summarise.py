#!/usr/bin/env python3
"""Tables for docs/experiments.md from the convergence.csv files that error_vs_time.sh writes:
per scene and group, each method's median photons, seconds and relative L2 error over the seeds at
the photon budgets 1e5 and 1e7, and the seconds its median error needs to fall below a target (the
largest of the methods' best errors times 1.1, so that every method reaches it; linear
interpolation in log-log between budgets). Usage: docs/figures/experiments/summarise.py ELEMENTS [SCENES...]"""
import csv
import math
import os
import sys
from collections import defaultdict

here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here)
from analysis import median  # noqa: E402

elements = sys.argv[1] if len(sys.argv) > 1 else "32"
scenes = sys.argv[2:] or ["penumbra", "curved_room", "room_reflector", "syndrome"]
for scene in scenes:
    for group in ("storage", "origins", "rays"):
        path = os.path.join(here, scene, "e" + elements, group, "convergence.csv")
        if not os.path.exists(path):
            continue
        runs = defaultdict(lambda: defaultdict(list))  # method -> budget index -> rows
        budgets = []
        with open(path) as f:
            rows = list(csv.DictReader(f))
        # Budgets are not in the CSV (the photons actually shot are); group by order of appearance:
        # each method's rows come budget by budget, seeds innermost.
        seeds = len({r["seed"] for r in rows})
        order = defaultdict(int)
        methods = []
        for r in rows:
            m = r["method"]
            if m not in methods:
                methods.append(m)
            runs[m][order[m] // seeds].append(r)
            order[m] += 1
        curves = {}
        for m in methods:
            points = []
            for b in sorted(runs[m]):
                rs = runs[m][b]
                points.append((median([float(r["seconds"]) for r in rs]), median([float(r["rel_l2"]) for r in rs]),
                               median([float(r["photons"]) for r in rs])))
            curves[m] = points
        target = 1.1 * max(min(e for _, e, _ in pts) for pts in curves.values())

        def time_to(points):
            for (t0, e0, _), (t1, e1, _) in zip(points, points[1:]):
                if e0 <= target:
                    return t0
                if e1 <= target:
                    f = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
                    return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
            return points[0][0] if points[0][1] <= target else float("nan")

        print("\n%s, %s, %s elements per curve (median of %d seeds; budgets 1e5 and 1e7):\n" % (scene, group, elements, seeds))
        print("| method | error at 1e5 | s | error at 1e7 | s | s to reach %.3g |" % target)
        print("|---|---|---|---|---|---|")
        for m in methods:
            pts = curves[m]
            a, b = pts[2], pts[-1]
            print("| %s | %.4f | %.3f | %.4f | %.2f | %.3f |" % (m, a[1], a[0], b[1], b[0], time_to(pts)))

#!/usr/bin/env python3
"""Issue 14, part 3: read DIR/<scene>/convergence.csv (written by run.sh) and print, per scene, the
median (over seeds) error of B - E and solve time of progressive shooting and of random walks at each
budget, the rays per walk, and each transport's time to 1 % and 0.1 % error (interpolated in log-log
between the two budgets whose median errors bracket the target; never extrapolated). Standard library
only."""
import csv, math, os, statistics, sys

SCENES = ["penumbra", "round_occluder", "lit_ring", "ring_profile", "curved_room"]
TRANSPORTS = ["shooting", "walk"]
TARGETS = [1e-2, 1e-3]


def medians(rows):
    by_budget = {}
    for r in rows:
        by_budget.setdefault(int(float(r["photons_asked"])), []).append(r)
    out = []
    for budget in sorted(by_budget):
        rs = by_budget[budget]
        out.append((budget, statistics.median(float(r["rel_l2"]) for r in rs),
                    statistics.median(float(r["seconds"]) for r in rs),
                    statistics.median(float(r["rays"]) / float(r["photons"]) for r in rs)))
    return out


def time_to(points, target):
    if not points:
        return "-"
    if points[0][1] <= target:
        return "< %.3g s" % points[0][2]
    for (b0, e0, t0, _), (b1, e1, t1, _) in zip(points, points[1:]):
        if e0 > target >= e1:
            f = (math.log(e0) - math.log(target)) / (math.log(e0) - math.log(e1))
            return "%.3g s" % math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
    return "not reached"


def main(directory):
    for scene in SCENES:
        path = os.path.join(directory, scene, "convergence.csv")
        if not os.path.exists(path):
            continue
        with open(path) as f:
            rows = list(csv.DictReader(f))
        # The budget asked for is the run's position in --budgets: runs come budget-major per method.
        budgets = os.environ.get("BUDGETS", "1e4,3e4,1e5,3e5,1e6,3e6,1e7").split(",")
        seeds = len({r["seed"] for r in rows})
        per = {}
        for r in rows:
            per.setdefault(r["transport"], []).append(r)
        for t, rs in per.items():
            for i, r in enumerate(rs):
                r["photons_asked"] = budgets[i // seeds]
        print("\n### %s\n" % scene)
        print("| budget | shooting error | shooting time | walk error | walk time | rays per walk |")
        print("|---:|---:|---:|---:|---:|---:|")
        m = {t: medians(per.get(t, [])) for t in TRANSPORTS}
        for i, budget in enumerate(b for b, *_ in m["shooting"]):
            s = m["shooting"][i]
            w = m["walk"][i] if i < len(m["walk"]) else None
            print("| %.0e | %.3g | %.3g s | %s | %s | %s |" % (
                budget, s[1], s[2], "%.3g" % w[1] if w else "-", "%.3g s" % w[2] if w else "-",
                "%.2f" % w[3] if w else "-"))
        print()
        for target in TARGETS:
            print("time to %g %%: shooting %s, walk %s  " % (
                100 * target, time_to(m["shooting"], target), time_to(m["walk"], target)))


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__)))

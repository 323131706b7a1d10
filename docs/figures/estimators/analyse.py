#!/usr/bin/env python3
"""Tables for docs/method.md "Estimators: measured" from the runs of estimators.sh.

Per run: the relative L2 error of B - E against the reference along arc length (midpoint rule over
the samples, every curve, side and channel: the number `flatland compare` prints as the scene's L2,
checked on the first run of each scene). Per configuration (scene, basis, estimator, elements,
photons) over its S seeds: the median error and time; the error of the seeds' mean B; and a split
of the error into bias and noise: with e_i = b + n_i (independent seeds, E n_i = 0),
E|e_i|^2 = |b|^2 + s^2 and E|mean e|^2 = |b|^2 + s^2 / S, so
s^2 = S / (S - 1) (mean |e_i|^2 - |mean e|^2) and |b|^2 = |mean e|^2 - s^2 / S (clipped at 0; with
3 seeds these are rough: a bias below about half the noise is not resolved).
"""
import argparse, csv, json, math, os, re, statistics, subprocess, sys
from collections import defaultdict

NAME = re.compile(r"^(\w+)-(\w+)-e(\d+)-p([0-9.e+]+)-s(\d+)\.(json|failed)$")


def values(doc):
    """Per curve, per side, per channel: (ds, [value per sample]) and the E per sample."""
    out = []
    for c in doc["curves"]:
        samples = c["samples"]
        ds = c["length"] / len(samples)
        for key in ("B", "B_back"):
            if key not in samples[0]:
                continue
            first = samples[0][key]
            chans = len(first) if isinstance(first, list) else 1
            for ch in range(chans):
                v = [(s[key][ch] if chans > 1 else s[key]) for s in samples]
                e = [((s["E"][ch] if isinstance(s["E"], list) else s["E"]) if "E" in s else 0.0)
                     for s in samples]
                out.append((ds, v, e))
    return out


def rel_l2(vals, ref):
    num = den = 0.0
    for (ds, v, _), (dr, r, e) in zip(vals, ref):
        for a, b, ee in zip(v, r, e):
            num += (a - b) ** 2 * ds
            rr = b - ee
            if abs(rr) < 1e-12 * abs(b):
                rr = 0.0
            den += rr * rr * ds
    return math.sqrt(num / den)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--flatland", default="build/flatland")
    ap.add_argument("--work", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("scenes", nargs="+")
    a = ap.parse_args()
    runs = []
    configs = defaultdict(list)
    failures = defaultdict(list)
    for scene in a.scenes:
        name = os.path.basename(scene)
        refdoc = json.load(open(os.path.join(a.work, f"{name}-reference.json")))
        ref = values(refdoc)
        d = os.path.join(a.work, name)
        checked = False
        for f in sorted(os.listdir(d)):
            m = NAME.match(f)
            if not m:
                continue
            basis, est, n, p, seed = m.group(1), m.group(2), int(m.group(3)), float(m.group(4)), int(m.group(5))
            path = os.path.join(d, f)
            if m.group(6) == "failed":
                failures[(name, basis, est, n, p)].append(open(path).read().strip())
                continue
            doc = json.load(open(path))
            vals = values(doc)
            err = rel_l2(vals, ref)
            if not checked:
                txt = subprocess.run([a.flatland, "compare", path, os.path.join(a.work, f"{name}-reference.json")],
                                     capture_output=True, text=True, check=True).stdout
                line = [l for l in txt.splitlines() if l.startswith("(scene)")][0]
                theirs = float(line.split()[2])
                if abs(theirs - err) > 1e-4 * err:
                    sys.exit(f"{path}: analyse.py L2 {err} != flatland compare {theirs}")
                checked = True
            t = doc["stats"]["seconds"]
            runs.append((name, basis, est, n, p, seed, err, t))
            neg = min(min(a - ee for a, ee in zip(v, e)) for _, v, e in vals)
            configs[(name, basis, est, n, p)].append((err, t, vals, neg))
    with open(os.path.join(a.out, "runs.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["scene", "basis", "estimator", "elements", "photons", "seed", "rel_l2_reflected", "seconds"])
        for r in sorted(runs):
            w.writerow(list(r[:6]) + [f"{r[6]:.6g}", f"{r[7]:.4g}"])
    summary = {}
    for key, msgs in failures.items():
        if key not in configs:
            summary[key] = dict(failed=len(msgs), message=msgs[0])
    for key, rs in configs.items():
        name = key[0]
        refdoc = json.load(open(os.path.join(a.work, f"{name}-reference.json")))
        ref = values(refdoc)
        S = len(rs)
        errs = [r[0] for r in rs]
        mean_vals = []
        for parts in zip(*[r[2] for r in rs]):
            ds = parts[0][0]
            v = [sum(x) / S for x in zip(*[p[1] for p in parts])]
            mean_vals.append((ds, v, parts[0][2]))
        emean = rel_l2(mean_vals, ref)
        ms = sum(e * e for e in errs) / S
        noise2 = S / (S - 1) * max(ms - emean ** 2, 0.0) if S > 1 else float("nan")
        bias2 = max(emean ** 2 - noise2 / S, 0.0) if S > 1 else float("nan")
        summary[key] = dict(median=statistics.median(errs), lo=min(errs), hi=max(errs),
                            time=statistics.median(r[1] for r in rs), mean_err=emean,
                            bias=math.sqrt(bias2), noise=math.sqrt(noise2), seeds=S,
                            min_reflected=min(r[3] for r in rs), failed=len(failures.get(key, [])))
    with open(os.path.join(a.out, "summary.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["scene", "basis", "estimator", "elements", "photons", "seeds", "median_rel_l2", "min", "max",
                    "mean_of_seeds_rel_l2", "bias", "noise_per_run", "median_seconds",
                    "min_reflected_sample", "failed_seeds"])
        for k in sorted(summary):
            s = summary[k]
            if "median" not in s:
                w.writerow(list(k) + [0] + ["fails"] * 8 + [s["failed"]])
                continue
            w.writerow(list(k) + [s["seeds"]] + [f"{s[x]:.4g}" for x in
                                                 ("median", "lo", "hi", "mean_err", "bias", "noise", "time",
                                                  "min_reflected")] + [s["failed"]])
    write_tables(a, summary)


def fmt(x):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.2g}" if x < 0.01 else f"{x:.3f}"


def pct(x):
    if x is None or math.isnan(x):
        return "-"
    x *= 100
    return f"{x:.2g}" if x < 10 else f"{x:.0f}"


def write_tables(a, summary):
    names = [os.path.basename(x) for x in a.scenes]
    scenes = sorted({k[0] for k in summary}, key=names.index)
    bases = [b for b in ("constant", "linear", "cubic", "hermite") if any(k[1] == b for k in summary)]
    ests = ["lumped", "galerkin", "local"]
    elements = sorted({k[3] for k in summary})
    photons = sorted({k[4] for k in summary})
    top = photons[-1]
    e_ = lambda p: f"{p:.0e}".replace("e+0", "e")

    def ok(key):
        return key in summary and "median" in summary[key]

    def cell(key, field, f=pct):
        if key not in summary:
            return "-"
        s = summary[key]
        if "median" not in s:
            return "fails"
        return f(s[field]) + ("*" if s["failed"] else "")

    lines = ["# Estimators: every configuration\n",
             "Written by docs/figures/estimators/estimators.sh (analyse.py); explained in docs/method.md, "
             "\"Estimators: measured\". Relative L2 error of B - E in %, median over the seeds; bias and "
             "per-run noise (%) from the split over seeds at the largest budget; median solve seconds per "
             "budget (shared machine: up to 2x load noise). `fails`: every seed stopped with an error "
             "(summary.csv); `*`: some seeds did.\n"]
    for scene in scenes:
        lines.append(f"## {scene}\n")
        head = ["basis", "estimator", "elements"] + [e_(p) for p in photons] + \
               [f"bias {e_(top)}", f"noise {e_(top)}", "seconds " + " / ".join(e_(p) for p in photons)]
        lines.append("| " + " | ".join(head) + " |")
        lines.append("|" + "---|" * len(head))
        for b in bases:
            for e in ests:
                for n in elements:
                    row = [b, e, str(n)] + [cell((scene, b, e, n, p), "median") for p in photons]
                    row += [cell((scene, b, e, n, top), "bias"), cell((scene, b, e, n, top), "noise")]
                    row.append(" / ".join(cell((scene, b, e, n, p), "time", lambda t: f"{t:.2g}") for p in photons))
                    lines.append("| " + " | ".join(row) + " |")
        lines.append("")
    lines.append("## Each estimator at its best storage size\n")
    lines.append("Smallest median over the element counts (the count in brackets); **bold**: within 5 % of "
                 "the basis's best estimator at that budget, when not all are.\n")
    head = ["scene", "basis"] + [f"{e} {e_(p)}" for p in photons for e in ests]
    lines.append("| " + " | ".join(head) + " |")
    lines.append("|" + "---|" * len(head))
    for scene in scenes:
        for b in bases:
            row = [scene, b]
            for p in photons:
                cells = {}
                for e in ests:
                    cand = [(summary[(scene, b, e, n, p)]["median"], n) for n in elements if ok((scene, b, e, n, p))]
                    cells[e] = min(cand) if cand else None
                vals = [v[0] for v in cells.values() if v]
                best = min(vals) if vals else None
                for e in ests:
                    v = cells[e]
                    failed = sum(1 for n in elements if (scene, b, e, n, p) in summary and not ok((scene, b, e, n, p)))
                    t = "-" if v is None else f"{pct(v[0])} ({v[1]})"
                    if failed:
                        t += f" [fails at {','.join(str(n) for n in elements if (scene, b, e, n, p) in summary and not ok((scene, b, e, n, p)))}]"
                    # Bold: within 5 % of the best estimator of the basis at this budget.
                    row.append(f"**{t}**" if v and len(vals) > 1 and v[0] <= 1.05 * best and
                               not all(x <= 1.05 * best for x in vals) else t)
            lines.append("| " + " | ".join(row) + " |")
    lines.append("")
    open(os.path.join(a.out, "tables.md"), "w").write("\n".join(lines))
    write_compact(a, summary, scenes, ok, cell, e_, elements, photons)


def write_compact(a, summary, scenes, ok, cell, e_, elements, photons):
    """The table of docs/method.md: 16 and 64 elements, every budget, the best size, the time."""
    shown = [n for n in (16, 64) if n in elements]
    lines = []
    head = ["scene", "basis", "estimator"] + [f"{n}: {e_(p)}" for n in shown for p in photons] + \
           [f"best {e_(p)}" for p in photons[1:]] + [f"s {e_(photons[-1])} ({shown[0]})"]
    lines.append("| " + " | ".join(head) + " |")
    lines.append("|" + "---|" * len(head))
    for scene in scenes:
        for b in ("constant", "linear", "cubic", "hermite"):
            for e in (["lumped"] if b == "constant" else ["lumped", "galerkin", "local"]):
                row = [scene.replace("reference_", ""), b, e]
                row += [cell((scene, b, e, n, p), "median") for n in shown for p in photons]
                for p in photons[1:]:
                    cand = [(summary[(scene, b, e, n, p)]["median"], n) for n in elements if ok((scene, b, e, n, p))]
                    row.append(f"{pct(min(cand)[0])} ({min(cand)[1]})" if cand else "-")
                row.append(cell((scene, b, e, shown[0], photons[-1]), "time", lambda t: f"{t:.1f}"))
                lines.append("| " + " | ".join(row) + " |")
    lines.append("")
    open(os.path.join(a.out, "compact.md"), "w").write("\n".join(lines))


if __name__ == "__main__":
    main()

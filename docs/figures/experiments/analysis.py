"""Helpers shared by the experiment scripts of docs/experiments.md: read flatland results (the
JSON of solve --out / reference --out) and measure them along arc length, with the same
midpoint-rule norms as flatland compare (samples sit at the midpoints of equal cells)."""
import json
import math


def load(path):
    with open(path) as f:
        return json.load(f)


def samples(result, curve_id=None):
    """Every B value of the result (front and back sides, every channel) in a fixed order, each
    with its cell length as weight; only curve `curve_id` if given."""
    values, weights = [], []
    for curve in result["curves"]:
        if curve_id is not None and curve["id"] != curve_id:
            continue
        cell = curve["length"] / len(curve["samples"])
        for sample in curve["samples"]:
            for key in ("B", "B_back"):
                if key in sample:
                    b = sample[key]
                    for value in (b if isinstance(b, list) else [b]):
                        values.append(value)
                        weights.append(cell)
    return values, weights


def l2(values, reference, weights):
    """Relative L2 distance of values from reference."""
    num = sum(w * (v - r) ** 2 for v, r, w in zip(values, reference, weights))
    den = sum(w * r * r for r, w in zip(reference, weights))
    return math.sqrt(num / den)


def bias_and_noise(runs, reference, weights):
    """runs: lists of values over seeds. Returns (relative L2 bias of their mean, relative L2 noise
    of one run, i.e. the root mean square distance of a run from the mean, corrected for the mean's
    own noise by K / (K - 1)), both relative to the reference's L2 norm."""
    k = len(runs)
    mean = [sum(column) / k for column in zip(*runs)]
    den = sum(w * r * r for r, w in zip(reference, weights))
    bias2 = sum(w * (m - r) ** 2 for m, r, w in zip(mean, reference, weights)) / den
    spread = sum(sum(w * (v - m) ** 2 for v, m, w in zip(run, mean, weights)) for run in runs) / den
    noise2 = spread / (k - 1)
    # The mean of k runs carries noise2 / k of its own: remove it from the bias estimate.
    return math.sqrt(max(bias2 - noise2 / k, 0.0)), math.sqrt(noise2)


def median(values):
    values = sorted(values)
    n = len(values)
    return values[n // 2] if n % 2 else 0.5 * (values[n // 2 - 1] + values[n // 2])


def reference_check(reference, smallest, curve=None, what="the smallest error judged"):
    """Says whether the reference is at least 10x more accurate than `smallest` (a relative L2 error
    of B on `curve`, or over the scene). The reference's own estimate (stats.estimated_error.l2,
    from its solves at two coarser resolutions) is relative to its B over the scene; over one curve
    its absolute error is at most the scene's, so relative to that curve it is at most
    estimate x |B|_scene / |B|_curve. Returns (ok, sentence)."""
    estimate = reference["stats"].get("estimated_error", {}).get("l2")
    if estimate is None:
        return False, "no estimate of its own error (made with --no-error-estimate)"
    r_all, w_all = samples(reference)
    r_curve, w_curve = samples(reference, curve)
    scene = math.sqrt(sum(w * r * r for r, w in zip(r_all, w_all)))
    part = math.sqrt(sum(w * r * r for r, w in zip(r_curve, w_curve)))
    floor = estimate * scene / part if part > 0 else float("inf")
    ok = 10 * floor <= smallest
    return ok, "%s: estimated error %.2g against %s %.2g: %s" % (
        curve or "scene", floor, what, smallest, "good enough" if ok else "NOT 10x below")

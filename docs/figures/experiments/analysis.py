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

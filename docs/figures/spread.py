"""The spread over seeds that every median in docs/tables carries: the interquartile range.

A table cell reads `MEDIAN [Q1–Q3]` (with the unit after each: `3.2 % [3.1–3.3 %]`), where Q1 and Q3 are the first and third quartiles by Python's
statistics.quantiles(n=4, method='inclusive'): for 5 seeds the second smallest and the second
largest value, for 3 seeds the midpoints between the smallest and the median and between the median
and the largest. One value has no spread and is printed alone."""
import statistics


def quartiles(values):
    """(first, third) quartile of `values` (inclusive method); (v, v) for a single value.

    >>> quartiles([5, 1, 4, 2, 3])  # 5 seeds: the second smallest and the second largest
    (2.0, 4.0)
    >>> quartiles([3, 1, 2])  # 3 seeds: midway to the median from either end
    (1.5, 2.5)
    >>> quartiles([7])
    (7, 7)
    """
    values = sorted(values)
    if len(values) < 2:
        return values[0], values[0]
    q = statistics.quantiles(values, n=4, method="inclusive")
    return q[0], q[2]


def cell(values, fmt=lambda v: "%.3g" % v, unit=""):
    """`MEDIAN [Q1–Q3]` of `values`, each number written by `fmt` and followed by `unit`.

    >>> cell([0.30, 0.10, 0.20, 0.50, 0.40], lambda v: "%.2f" % v, " s")
    '0.30 s [0.20–0.40 s]'
    >>> cell([2.5])
    '2.5'
    """
    m = statistics.median(values)
    if len(values) < 2:
        return fmt(m) + unit
    lo, hi = quartiles(values)
    return "%s%s [%s–%s%s]" % (fmt(m), unit, fmt(lo), fmt(hi), unit)


def percent(values):
    """cell() of relative errors in percent, two digits.

    >>> percent([0.031, 0.032, 0.033, 0.030, 0.034])
    '3.2 % [3.1–3.3 %]'
    """
    return cell([100 * v for v in values], lambda v: "%.2g" % v, " %")


def caption(seeds, what="seeds"):
    """The words a table's caption uses for its cells' spread."""
    return ("median [its interquartile range over the %d %s: the first and third quartiles by Python's "
            "statistics.quantiles(method='inclusive')]" % (seeds, what))

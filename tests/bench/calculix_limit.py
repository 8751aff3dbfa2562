"""The limit h -> 0 of a conforming reference (CalculiX tet10) from runs at three mesh sizes,
for benchmarks whose errors must be measured below the finest run's own error.

u(h) = u0 + c h^p: the observed order p from the three values (bisection on
(h3^p - h2^p) / (h2^p - h1^p) = (u3 - u2) / (u2 - u1)), then u0 (Richardson). Also u0 for p = 1,
whose distance from u0 is a rough measure of the extrapolation's uncertainty.
"""
import json
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
LIMITS = os.path.normpath(os.path.join(HERE, "..", "reference", "calculix_limits.json"))


def extrapolated_limit(runs):
    """runs: (h, u) pairs; the three smallest h are used. None when there are fewer than three,
    the values are not monotone in h, or no order in [0.2, 4] fits."""
    runs = sorted(runs)
    if len(runs) < 3:
        return None
    (h1, u1), (h2, u2), (h3, u3) = runs[:3]
    if not (h1 < h2 < h3) or (u3 - u2) * (u2 - u1) <= 0:
        return None
    ratio = (u3 - u2) / (u2 - u1)
    f = lambda p: (h3 ** p - h2 ** p) / (h2 ** p - h1 ** p) - ratio
    lo, hi = 0.2, 4.0
    if f(lo) * f(hi) > 0:
        return None
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if f(lo) * f(mid) <= 0 else (mid, hi)
    p = 0.5 * (lo + hi)
    u0 = u1 - (u2 - u1) / ((h2 / h1) ** p - 1)
    u0_first = u1 - (u2 - u1) / ((h2 / h1) - 1)
    return {"order": p, "u_probe": u0, "sizes": [h1, h2, h3], "values": [u1, u2, u3],
            "finest_error": abs(u1 - u0) / abs(u0), "u_probe_first_order": u0_first,
            "uncertainty": abs(u0_first - u0) / abs(u0)}


def kept_runs(case, size, u_fresh, tolerance=1e-6):
    """The runs kept in tests/reference/calculix_limits.json for `case`, if the kept value at mesh
    size `size` agrees with a fresh run's `u_fresh` (same part, job and tools); else None and why."""
    if not os.path.exists(LIMITS):
        return None, "no " + LIMITS
    with open(LIMITS) as f:
        entry = json.load(f).get(case)
    if not entry:
        return None, "no entry for " + case
    same = [r for r in entry["runs"] if r["size"] == size]
    if not same:
        return None, "no kept run at h = %g" % size
    if abs(same[0]["u_probe"] - u_fresh) > tolerance * abs(u_fresh):
        return None, "the kept h = %g run (%.8g) differs from this run's (%.8g)" % (size, same[0]["u_probe"], u_fresh)
    return [(r["size"], r["u_probe"]) for r in entry["runs"]], None


def loglog_interp(x, xs, ys):
    """y at x on the piecewise log–log line through (xs, ys) sorted by xs; None outside."""
    pts = sorted(zip(xs, ys))
    for (x0, y0), (x1, y1) in zip(pts, pts[1:]):
        if min(x0, x1) <= x <= max(x0, x1) and x0 != x1:
            t = (math.log(x) - math.log(x0)) / (math.log(x1) - math.log(x0))
            return math.exp(math.log(y0) + t * (math.log(y1) - math.log(y0)))
    return None

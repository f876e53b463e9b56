"""Fitting a detection confidence (the calibration file scripts/calibrate.py writes) and measuring it.

A class's map is a logistic regression on features of the detection (by default the log of its
raw score: Platt scaling), fitted by Newton's method with a small L2 penalty on the slopes (the
features are standardised first, and the fitted map is written back in their raw units). Labels
are true positives at 3D IoU >= 0.25 as `furnihost eval` matches them for AP25 (VoteNet's
eval_det_cls: detections by descending score). Only the Python standard library.
"""
import math

# What a detection's feature is: "log_score" (ln of its raw score, floored at 1e-6), "evidence:NAME"
# (its evidence value NAME, 0 without), "log_evidence:NAME" (its ln, floored at 1e-6).
DEFAULT_FEATURES = ["log_score"]


def feature_value(name, score, evidence):
    if name == "log_score":
        return math.log(max(score, 1e-6))
    if name.startswith("log_evidence:"):
        return math.log(max(float(evidence.get(name[13:], 0.0)), 1e-6))
    if name.startswith("evidence:"):
        return float(evidence.get(name[9:], 0.0))
    raise ValueError("unknown calibration feature " + name)


def _solve(a, b):
    """Gaussian elimination with partial pivoting of a small dense system."""
    n = len(b)
    m = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[p] = m[p], m[c]
        if abs(m[c][c]) < 1e-12:
            continue
        for r in range(n):
            if r != c:
                f = m[r][c] / m[c][c]
                for k in range(c, n + 1):
                    m[r][k] -= f * m[c][k]
    return [m[i][n] / m[i][i] if abs(m[i][i]) > 1e-12 else 0.0 for i in range(n)]


def sigmoid(z):
    if z >= 0:
        return 1.0 / (1.0 + math.exp(-z))
    e = math.exp(z)
    return e / (1.0 + e)


def fit_logistic(x, y, l2=0.01, iterations=60):
    """x: rows of feature values, y: 0/1 labels. Returns (coef, intercept) in the raw units of x."""
    d = len(x[0]) if x else 0
    mean = [sum(r[k] for r in x) / len(x) for k in range(d)] if x else [0.0] * d
    scale = [max(1e-9, (sum((r[k] - mean[k]) ** 2 for r in x) / len(x)) ** 0.5) for k in range(d)] if x else [1.0] * d
    z = [[(r[k] - mean[k]) / scale[k] for k in range(d)] for r in x]
    beta = [0.0] * (d + 1)  # intercept first
    for _ in range(iterations):
        h = [[0.0] * (d + 1) for _ in range(d + 1)]
        g = [0.0] * (d + 1)
        for row, t in zip(z, y):
            xx = [1.0] + row
            p = sigmoid(sum(b * v for b, v in zip(beta, xx)))
            w = p * (1.0 - p)
            for i in range(d + 1):
                g[i] += (t - p) * xx[i]
                for j in range(d + 1):
                    h[i][j] += w * xx[i] * xx[j]
        # The intercept gets a faint penalty too: a class without a single true positive then has a
        # finite (very negative) intercept instead of none.
        for i in range(d + 1):
            pen = l2 if i > 0 else 1e-4
            g[i] -= pen * beta[i]
            h[i][i] += pen
        step = _solve(h, g)
        beta = [b + s for b, s in zip(beta, step)]
        if max(abs(s) for s in step) < 1e-9:
            break
    coef = [beta[k + 1] / scale[k] for k in range(d)]
    intercept = beta[0] - sum(beta[k + 1] * mean[k] / scale[k] for k in range(d))
    return coef, intercept


def confidence(coef, intercept, features):
    return sigmoid(intercept + sum(c * v for c, v in zip(coef, features)))


def reliability(pairs, bins=10):
    """pairs: [(confidence, tp)]. Returns (ece, [(lo, hi, n, mean confidence, TP share)])."""
    rows = []
    total, ece = 0, 0.0
    for b in range(bins):
        lo, hi = b / bins, (b + 1) / bins
        inside = [(c, t) for c, t in pairs if (lo <= c < hi) or (b == bins - 1 and c >= hi)]
        if not inside:
            rows.append((lo, hi, 0, float("nan"), float("nan")))
            continue
        mc = sum(c for c, _ in inside) / len(inside)
        acc = sum(1 for _, t in inside if t) / len(inside)
        rows.append((lo, hi, len(inside), mc, acc))
        total += len(inside)
        ece += len(inside) * abs(acc - mc)
    return (ece / total if total else float("nan")), rows


def working_point(pairs, npos, threshold=0.5):
    """pairs: [(confidence, tp)]: precision and recall of those at or above `threshold`."""
    kept = [t for c, t in pairs if c >= threshold]
    tp = sum(1 for t in kept if t)
    p = tp / len(kept) if kept else float("nan")
    r = tp / npos if npos else float("nan")
    return tp, len(kept) - tp, p, r

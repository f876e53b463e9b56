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


def _volume(box):
    v = 1.0
    for k in range(3):
        v *= max(0.0, box[1][k] - box[0][k])
    return v


def _iou(a, b):
    inter = _volume(([max(a[0][k], b[0][k]) for k in range(3)], [min(a[1][k], b[1][k]) for k in range(3)]))
    u = _volume(a) + _volume(b) - inter
    return inter / u if u > 0 else 0.0


def part_of_pairs(items):
    """calibration.part_of as the graph gives it ("chair:sofa, ...") as [(part, whole)]."""
    pairs = []
    for item in [x.strip() for x in (items or "").split(",") if x.strip()]:
        part, _, whole = item.partition(":")
        pairs.append((part.strip(), whole.strip()))
    return pairs


def drop_parts(dets, pairs, share, min_confidence):
    """The host's DropParts (framework/src/host/calibration.cpp) on one scan's detections: dicts with
    "cls", "box" ((lo, hi)) and "confidence" (None without a map), accepted when their confidence is
    at least min_confidence. Returns the detections kept, in their order."""
    drop = set()
    for part, whole in pairs:
        for w, W in enumerate(dets):
            if W["cls"] != whole or W["confidence"] is None or W["confidence"] < min_confidence or _volume(W["box"]) <= 0:
                continue
            inside = []
            for p, P in enumerate(dets):
                if P["cls"] != part or P["confidence"] is None:
                    continue
                v = _volume(P["box"])
                lo = [max(P["box"][0][k], W["box"][0][k]) for k in range(3)]
                hi = [min(P["box"][1][k], W["box"][1][k]) for k in range(3)]
                if v > 0 and _volume((lo, hi)) >= share * v:
                    inside.append(p)
            if not inside:
                continue
            inside.sort(key=lambda p: -dets[p]["confidence"])  # stable, as the host's
            chosen, together = [], 0.0
            for p in inside:
                if all(_iou(dets[p]["box"], dets[q]["box"]) < 0.25 for q in chosen):
                    chosen.append(p)
                    together += dets[p]["confidence"]
            if together > W["confidence"]:
                continue
            drop.update(inside)
    return [d for i, d in enumerate(dets) if i not in drop]

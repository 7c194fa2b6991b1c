"""Does the object's imprint moving against the markers tell slip on the real GelSight grasps?

The study behind the perf-log entry "Slip: the imprint moving against the dots" (issue 63).
A GelSight Mini's markers are printed on the gel; the object's imprint is the shading it presses
into the gel. While the object sticks both move together; when it slips the imprint slides over
the markers. Per frame pair (t - STEP, t), on gray frames halved to 160 x 120:

- the dots: pixels darker than their blurred surroundings (sigma 4 px) by 12 grey levels;
- the shading: the frame with the dots filled in from their surroundings (normalised
  convolution, sigma 2 px), minus the sequence's first frame filled the same way;
- the contact: the pixels whose shading change is in its top 10 % (and at least 4 levels);
- the imprint's shift: the integer shift within +-3 px (then a parabola through its neighbours)
  that best aligns the shading change at t - STEP with the one at t over the contact;
- the markers' shift: the same alignment of the dot images over the contact (blurred);
- the imprint's slide: the length of the difference of the two shifts.

Per video: the mean, 90th percentile, largest and sum of the slide, and the contact's mean area.
These are added to the thirty statistics `visuotact slip fit --cv-table cv.csv` writes, and a
logistic regression is cross-validated leaving one object out, per video and with the grasp's two
sensors fused (log-odds added), as `slip fit --grasp-per-folder` does.

Needs: ffmpeg, numpy, scikit-learn; `../shared/reference/real/gelsight_slip` (or
$VISUOTACT_SHARED/reference/real/gelsight_slip); the table from, in that folder,
`visuotact slip fit --labels labels.csv --cv-by object -o slip.json --cv-table cv.csv videos`.

Usage: python research/gelsight_slip_imprint.py CV.csv [STEP]   (about 7 minutes on 2 cores)
"""

import csv
import os
import subprocess
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.metrics import balanced_accuracy_score
from sklearn.model_selection import LeaveOneGroupOut
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler

W, H = 320, 240
SHARED = os.environ.get("VISUOTACT_SHARED", os.path.join(os.path.dirname(__file__), "../../shared"))
ROOT = os.path.join(SHARED, "reference/real/gelsight_slip")


def gray_frames(path):
    raw = subprocess.run(
        ["ffmpeg", "-loglevel", "error", "-i", path, "-f", "rawvideo", "-pix_fmt", "gray", "-"],
        capture_output=True,
        check=True,
    ).stdout
    return np.frombuffer(raw, np.uint8).reshape(-1, H, W).astype(np.float32)


def blurred(a, sigma):
    r = int(3 * sigma)
    k = np.exp(-np.arange(-r, r + 1) ** 2 / (2 * sigma * sigma))
    k /= k.sum()
    p = np.pad(a, r, mode="edge")
    t = sum(k[i] * p[:, i : i + a.shape[1]] for i in range(2 * r + 1))
    return sum(k[i] * t[i : i + a.shape[0], :] for i in range(2 * r + 1))


def halved(a):
    return 0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2])


def shift_between(a, b, w, reach=3):
    """The shift s (dy, dx) minimising the w-weighted squared difference a(x) - b(x - s)."""
    h, wd = a.shape
    cost = np.full((2 * reach + 1, 2 * reach + 1), np.inf)
    ac, wc = a[reach : h - reach, reach : wd - reach], w[reach : h - reach, reach : wd - reach]
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            bs = b[reach - dy : h - reach - dy, reach - dx : wd - reach - dx]
            cost[dy + reach, dx + reach] = (wc * (ac - bs) ** 2).sum() / (wc.sum() + 1e-9)
    i, j = np.unravel_index(np.argmin(cost), cost.shape)

    def vertex(c0, cm, cp):
        d = cm - 2 * c0 + cp
        return 0.0 if d <= 0 else 0.5 * (cm - cp) / d

    sy = vertex(cost[i, j], cost[i - 1, j], cost[i + 1, j]) if 0 < i < 2 * reach else 0.0
    sx = vertex(cost[i, j], cost[i, j - 1], cost[i, j + 1]) if 0 < j < 2 * reach else 0.0
    return np.array([i - reach + sy, j - reach + sx])


def imprint_statistics(path, step):
    dots, shading = [], []
    for g in (halved(f) for f in gray_frames(path)):
        bg = blurred(g, 4)
        keep = 1 - np.clip(blurred((g < bg - 12).astype(np.float32), 1.0) * 4, 0, 1)
        dots.append(bg - g)
        shading.append((blurred(g * keep, 2) / (blurred(keep, 2) + 1e-3), keep))
    ref = shading[0][0]
    slide, area = [], []
    for t in range(step, len(dots), step):
        now, before = shading[t][0] - ref, shading[t - step][0] - ref
        change = np.abs(now)
        w = (change >= max(4.0, np.percentile(change, 90))) * shading[t][1] * shading[t - step][1]
        if w.sum() < 50:
            slide.append(0.0)
            area.append(0.0)
            continue
        imprint = shift_between(now, before, w)
        markers = shift_between(dots[t], dots[t - step], np.clip(blurred(w, 3) * 3, 0, 1))
        slide.append(float(np.hypot(*(imprint - markers))))
        area.append(float(w.sum()))
    s = np.array(slide or [0.0])
    return [s.mean(), np.percentile(s, 90), s.max(), s.sum(), np.mean(area or [0.0])]


def held_out(x, y, groups, folders):
    p = np.zeros(len(y))
    for tr, te in LeaveOneGroupOut().split(x, y, groups):
        m = make_pipeline(StandardScaler(), LogisticRegression(max_iter=2000)).fit(x[tr], y[tr])
        p[te] = m.predict_proba(x[te])[:, 1]
    logit = np.log(np.clip(p, 1e-6, 1 - 1e-6) / np.clip(1 - p, 1e-6, 1))
    fused = np.zeros(len(y))
    for f in set(folders):
        fused[folders == f] = logit[folders == f].sum()
    return balanced_accuracy_score(y, p > 0.5), balanced_accuracy_score(y, fused > 0)


def main():
    rows = list(csv.DictReader(open(sys.argv[1])))
    step = int(sys.argv[2]) if len(sys.argv) > 2 else 2
    videos = [os.path.join(ROOT, r["video"]) for r in rows]
    with ProcessPoolExecutor() as ex:
        imprint = np.array(list(ex.map(imprint_statistics, videos, [step] * len(videos))))
    y = np.array([int(r["slip"]) for r in rows])
    groups = np.array([r["group"] for r in rows])
    folders = np.array([os.path.dirname(r["video"]) for r in rows])
    names = [k for k in rows[0] if k.startswith(("max_", "mean_"))]
    base = np.array([[float(r[k]) for k in names] for r in rows])
    print("statistics, leave one object out\tper video\tgrasp fused")
    for name, x in [
        ("the thirty field statistics", base),
        ("the imprint's slide alone", imprint[:, :4]),
        ("thirty + the slide's mean", np.hstack([base, imprint[:, :1]])),
        ("thirty + all five imprint statistics", np.hstack([base, imprint])),
    ]:
        per, fused = held_out(x, y, groups, folders)
        print(f"{name}\t{per:.3f}\t{fused:.3f}")
    for k, name in enumerate(["mean", "p90", "max", "sum", "contact area"]):
        print(f"slide {name}: median {np.median(imprint[y == 1, k]):.3f} on slips, "
              f"{np.median(imprint[y == 0, k]):.3f} on the others")


if __name__ == "__main__":
    main()

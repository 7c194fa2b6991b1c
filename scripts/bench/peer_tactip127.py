"""The naive peer on the real 127-pin TacTip set: what a Python user writes in an afternoon.

OpenCV finds the pins in every frame (Otsu, 3x3 opening, connectedComponentsWithStats, blobs of
at least 4 px), the reference pins are the first training frame's, each reference pin takes the
nearest blob of every frame (no gate: a pin always gets a blob), the pins' (dx, dy) go into a
standardised scikit-learn MLP(64, 64) (Adam, early stopping) predicting the targets together.

  python peer_tactip127.py DATA_DIR [--seed N] [--json OUT]
      [--train CSV --test CSV --targets COL:NAME,...]

DATA_DIR is ../shared/reference/real/tactip127_surface (its train_targets.csv and
test_targets.csv keyed by image_name); --train, --test and --targets give another set's split
(keyed by image_name or sensor_image, frames in DATA_DIR/frames), as scripts/bench/real-tactip331
does. Prints the mean absolute error of each target on the test split, the fit's seconds and
the extraction's microseconds per frame.
"""
import argparse
import csv
import json
import os
import sys
import time

sys.path.insert(0, os.environ.get("PEERS_DIR", ""))
try:
    import peer_common  # noqa: F401  (one thread, tuned malloc, as the other peers)
except ImportError:
    pass

import cv2
import numpy as np
from scipy.spatial import cKDTree
from sklearn.neural_network import MLPRegressor
from sklearn.preprocessing import StandardScaler

TARGETS = [("pose_2", "y_mm"), ("pose_6", "rotation_deg"), ("move_1", "shear_x_mm"),
           ("move_6", "twist_deg")]


def centroids(path):
    grey = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    _, bw = cv2.threshold(grey, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    bw = cv2.morphologyEx(bw, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    n, _, stats, cent = cv2.connectedComponentsWithStats(bw, connectivity=8)
    keep = [i for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] >= 4]
    return cent[keep]


def rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def key(row):
    return row["image_name"] if "image_name" in row else row["sensor_image"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("data")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json")
    ap.add_argument("--train")
    ap.add_argument("--test")
    ap.add_argument("--targets", help="COL:NAME,... (default: the 127-pin set's four)")
    a = ap.parse_args()
    targets = TARGETS if not a.targets else [tuple(t.split(":")) for t in a.targets.split(",")]
    train = rows(a.train or os.path.join(a.data, "train_targets.csv"))
    test = rows(a.test or os.path.join(a.data, "test_targets.csv"))
    frame = lambda r: os.path.join(a.data, "frames", key(r))  # noqa: E731
    ref = centroids(frame(train[0]))
    t0 = time.perf_counter()

    def features(part):
        out = []
        for r in part:
            c = centroids(frame(r))
            _, j = cKDTree(c).query(ref)
            out.append((c[j] - ref).ravel())
        return np.array(out)

    xtr, xte = features(train), features(test)
    extract_us = (time.perf_counter() - t0) / (len(train) + len(test)) * 1e6
    ytr = np.array([[float(r[k]) for k, _ in targets] for r in train])
    yte = np.array([[float(r[k]) for k, _ in targets] for r in test])
    xs, ys = StandardScaler().fit(xtr), StandardScaler().fit(ytr)
    net = MLPRegressor(hidden_layer_sizes=(64, 64), max_iter=2000, early_stopping=True,
                       random_state=a.seed)
    t0 = time.perf_counter()
    net.fit(xs.transform(xtr), ys.transform(ytr))
    fit_s = time.perf_counter() - t0
    p = ys.inverse_transform(net.predict(xs.transform(xte)))
    mae = np.abs(p - yte).mean(axis=0)
    print(f"peer (OpenCV nearest blob + MLP(64,64)): {len(ref)} pins, train {len(xtr)}, "
          f"test {len(xte)}, fit {fit_s:.1f} s, extraction {extract_us:.0f} us/frame")
    print("  " + " ".join(f"{name}={e:.4f}" for (_, name), e in zip(targets, mae)))
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"pins": len(ref), "fit_s": fit_s, "extract_us": extract_us,
                       "mae": {name: float(e) for (_, name), e in zip(targets, mae)}}, f)


if __name__ == "__main__":
    main()

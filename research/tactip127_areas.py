"""Whether the pins' area changes help a learner read the real 127-pin TacTip set.

Fits scikit-learn MLPs (128, 128 and 64, 64; five seeds, their mean as an ensemble) on the
feature table `scripts/bench/real-tactip127` extracted ($PEER_WORK/tactip127/features.csv) and the
data set's own train/test split, twice: every marker's dx, dy and darea, then dx and dy alone,
and prints each one's test mean absolute error per target (y mm, rotation deg, shear mm, twist
deg). The binarised pins' areas move in whole pixels; this is the check behind the training's
input set without the markers' shape columns (docs/benchmarks.md).

Usage (after scripts/bench/real-tactip127; the peers' venv):
    $PEER_WORK/venv/bin/python research/tactip127_areas.py
"""
import csv
import os

import numpy as np
from sklearn.neural_network import MLPRegressor
from sklearn.preprocessing import StandardScaler

root = os.path.dirname(os.path.abspath(__file__))
shared = os.environ.get("VISUOTACT_SHARED", os.path.join(root, "..", "..", "shared"))
data = os.path.join(shared, "reference", "real", "tactip127_surface")
work = os.environ.get("PEER_WORK", "/tmp/visuotact-peers")
rows = list(csv.reader(open(os.path.join(work, "tactip127", "features.csv"))))
header = rows[0]
features = {r[0].split("/")[-1]: r for r in rows[1:]}
targets = ["pose_2", "pose_6", "move_1", "move_6"]


def split(name):
    labels = list(csv.DictReader(open(os.path.join(data, name))))
    return [features[r["image_name"]] for r in labels], np.array(
        [[float(r[t]) for t in targets] for r in labels])


(tr, y), (te, yt) = split("train_targets.csv"), split("test_targets.csv")
ys = StandardScaler().fit(y)
markers = [i for i, c in enumerate(header) if c[:1] == "m" and c[1:4].isdigit()]
sets = {
    "dx, dy, darea": markers,
    "dx, dy": [i for i in markers if not header[i].endswith("_darea_px")],
}


def table(frames, cols):
    return np.array([[float(r[i]) if r[i] != "" else np.nan for i in cols] for r in frames])


for name, cols in sets.items():
    # A lost pin's features: the training mean.
    x, xt = table(tr, cols), table(te, cols)
    mean = np.nanmean(x, 0)
    x, xt = np.where(np.isnan(x), mean, x), np.where(np.isnan(xt), mean, xt)
    sc = StandardScaler().fit(x)
    for hidden in [(128, 128), (64, 64)]:
        ps = []
        for seed in range(5):
            m = MLPRegressor(hidden_layer_sizes=hidden, max_iter=300, early_stopping=True,
                             random_state=seed)
            m.fit(sc.transform(x), ys.transform(y))
            ps.append(ys.inverse_transform(m.predict(sc.transform(xt))))
        one = np.abs(ps[0] - yt).mean(0)
        ens = np.abs(np.mean(ps, 0) - yt).mean(0)
        print(f"{name:14s} MLP{hidden}: one network " + " ".join(f"{v:.4f}" for v in one)
              + ", five " + " ".join(f"{v:.4f}" for v in ens), flush=True)

"""How far shear and twist can be read from the pins of the real 127-pin TacTip set.

Fits other learners on the same feature table `scripts/bench/real-tactip127` extracted
($PEER_WORK/tactip127/features.csv, every marker's dx, dy, darea and the field summary) and the
data set's own train/test split, and prints each one's test mean absolute error, then the
gradient-boosted trees' shear error by shear size and by indentation depth, and how the
residual correlates with the previous touch's labels (skin memory).

Usage (after scripts/bench/real-tactip127; the peers' venv, with pandas):
    $PEER_WORK/venv/bin/python research/tactip127_ceiling.py
"""
import os
import sys
import time

import numpy as np
import pandas as pd
from sklearn.ensemble import HistGradientBoostingRegressor
from sklearn.linear_model import Ridge
from sklearn.neural_network import MLPRegressor
from sklearn.preprocessing import StandardScaler

root = os.path.dirname(os.path.abspath(__file__))
shared = os.environ.get("VISUOTACT_SHARED", os.path.join(root, "..", "..", "shared"))
data = os.path.join(shared, "reference", "real", "tactip127_surface")
work = os.environ.get("PEER_WORK", "/tmp/visuotact-peers")
f = pd.read_csv(os.path.join(work, "tactip127", "features.csv"))
f["image_name"] = f["frame"].astype(str).map(lambda s: s.split("/")[-1])
tr = pd.read_csv(os.path.join(data, "train_targets.csv"))
te = pd.read_csv(os.path.join(data, "test_targets.csv"))
cols = [c for c in f.columns if c[:1] == "m" and c[1:4].isdigit()]
cols += ["shift_x_px", "shift_y_px"] + [c for c in f.columns if c.startswith("field_")]
a, b = tr.merge(f, on="image_name"), te.merge(f, on="image_name")
sc = StandardScaler().fit(a[cols].fillna(0).values)
x, xt = sc.transform(a[cols].fillna(0).values), sc.transform(b[cols].fillna(0).values)
targets = ["pose_2", "pose_6", "move_1", "move_6"]
y, yt = a[targets].values, b[targets].values
ys = StandardScaler().fit(y)


def report(name, p):
    print(name, " ".join(f"{t}={np.abs(p[:, i] - yt[:, i]).mean():.4f}" for i, t in enumerate(targets)), flush=True)


report("ridge", ys.inverse_transform(Ridge(1.0).fit(x, ys.transform(y)).predict(xt)))
for h in [(256, 256), (512, 256, 128)]:
    t0 = time.time()
    m = MLPRegressor(hidden_layer_sizes=h, max_iter=600, early_stopping=True, random_state=0, alpha=1e-3)
    m.fit(x, ys.transform(y))
    report(f"mlp{h} ({time.time() - t0:.0f} s)", ys.inverse_transform(m.predict(xt)))
p = np.zeros_like(yt)
for i in range(len(targets)):
    p[:, i] = HistGradientBoostingRegressor(max_iter=500, random_state=0).fit(x, y[:, i]).predict(xt)
report("gradient-boosted trees", p)
e, s = np.abs(p[:, 2] - yt[:, 2]), np.abs(yt[:, 2])
for lo, hi in [(0, 0.5), (0.5, 1), (1, 1.5), (1.5, 2.01)]:
    k = (s >= lo) & (s < hi)
    bias = np.mean((p[k, 2] - yt[k, 2]) * np.sign(yt[k, 2]))
    print(f"|move_1| {lo}-{hi} mm: {k.sum()} frames, mae {e[k].mean():.3f} mm, bias towards 0 {bias:.3f} mm")
d = yt[:, 0]
for lo, hi in [(-2, -1), (-1, 0), (0, 1), (1, 2.01)]:
    k = (d >= lo) & (d < hi)
    print(f"pose_2 {lo}..{hi} mm: move_1 mae {e[k].mean():.3f} mm, move_6 mae {np.abs(p[k, 3] - yt[k, 3]).mean():.3f} deg")
labels = pd.concat([tr, te])
labels["n"] = labels["data_name"].str.split("_").str[1].astype(int)
labels = labels.set_index("n").sort_index()
n = b["data_name"].str.split("_").str[1].astype(int).values
ok = np.isin(n - 1, labels.index)
prev = labels.loc[n[ok] - 1]
r1, r6 = (p[:, 2] - yt[:, 2])[ok], (p[:, 3] - yt[:, 3])[ok]
print(f"residual vs previous touch: corr(move_1) {np.corrcoef(r1, prev['move_1'].values)[0, 1]:.3f}, "
      f"corr(move_6) {np.corrcoef(r6, prev['move_6'].values)[0, 1]:.3f}")
sys.exit(0)

"""Whether the real 127-pin TacTip frames carry shear and twist beyond the pins' positions.

Fits scikit-learn learners (ridge; an MLP on 100 principal components) on the data set's own
train/test split from other inputs than visuotact's pin displacements: the whole frame (blurred,
64 x 64), the tip's rim alone (the ring outside 26 of those pixels from the centre), and each
pin's second moments (the shape of its blob, as a tilted pin would change it), each beside the
pins' displacements where that makes sense. Prints every learner's mean absolute error per
target. Companion of research/tactip127_ceiling.py (other learners on visuotact's own features).

Usage (after scripts/bench/real-tactip127, whose sensor file and features it reads; the peers' venv):
    $PEER_WORK/venv/bin/python research/tactip127_image_learners.py
"""

import csv
import json
import os

import numpy as np
from PIL import Image
from scipy import ndimage
from sklearn.decomposition import PCA
from sklearn.linear_model import Ridge
from sklearn.neural_network import MLPRegressor
from sklearn.preprocessing import StandardScaler

TARGETS = ["pose_2", "pose_6", "move_1", "move_6"]


def main(data, features_csv, sensor_json):
    rows = {r["frame"].split("/")[-1]: r for r in csv.DictReader(open(features_csv))}
    cols = [c for c in next(iter(rows.values())) if c.startswith("m") and c[1:4].isdigit()]
    ref = np.array([[m["x_px"], m["y_px"]] for m in json.load(open(sensor_json))["markers"]])
    split = {}
    for part in ("train", "test"):
        split[part] = list(csv.DictReader(open(f"{data}/{part}_targets.csv")))
    names = [r["image_name"] for part in ("train", "test") for r in split[part]]
    pos, pix, shape = {}, {}, {}
    for n in names:
        r = rows[n]
        pos[n] = np.array([float(r[c]) if r[c] != "" else 0.0 for c in cols])
        im = np.array(Image.open(f"{data}/frames/{n}").convert("L"), dtype=np.float32) / 255
        pix[n] = ndimage.gaussian_filter(im, 1.5)[::4, ::4].ravel()
        shape[n] = pin_moments(im > 0.5, ref, r)
    yy, xx = np.mgrid[:64, :64]
    ring = (np.hypot(xx - 31.5, yy - 31.5) > 26).ravel()
    inputs = {
        "pins (visuotact's features)": lambda n: pos[n],
        "pins' second moments": lambda n: shape[n],
        "pins + their moments": lambda n: np.concatenate([pos[n], shape[n]]),
        "whole frame, 64 x 64": lambda n: pix[n],
        "rim alone": lambda n: pix[n][ring],
        "pins + rim": lambda n: np.concatenate([pos[n], pix[n][ring]]),
    }
    y = {p: np.array([[float(r[t]) for t in TARGETS] for r in split[p]]) for p in split}
    print("| inputs | learner | y mm | rotation ° | shear x mm | twist ° |")
    print("|---|---|---|---|---|---|")
    for what, f in inputs.items():
        a = np.array([f(r["image_name"]) for r in split["train"]])
        b = np.array([f(r["image_name"]) for r in split["test"]])
        sc = StandardScaler().fit(a)
        a, b = sc.transform(a), sc.transform(b)
        pca = PCA(min(100, a.shape[1]), random_state=0).fit(a)
        ys = StandardScaler().fit(y["train"])
        learners = [
            ("ridge", Ridge(alpha=10.0), a, b),
            (
                "MLP(128, 128) on 100 components",
                MLPRegressor(
                    hidden_layer_sizes=(128, 128),
                    max_iter=500,
                    early_stopping=True,
                    random_state=0,
                    alpha=1e-2,
                ),
                pca.transform(a),
                pca.transform(b),
            ),
        ]
        for name, model, xa, xb in learners:
            model.fit(xa, ys.transform(y["train"]))
            e = np.abs(ys.inverse_transform(model.predict(xb)) - y["test"]).mean(0)
            print(f"| {what} | {name} | {e[0]:.3f} | {e[1]:.2f} | {e[2]:.3f} | {e[3]:.2f} |", flush=True)


def pin_moments(mask, ref, row):
    """Per pin: the second moments (xx - yy, 2 xy, xx + yy) of the blob at its measured place."""
    lab, k = ndimage.label(mask, structure=np.ones((3, 3)))
    idx = np.arange(1, k + 1)
    yy, xx = np.mgrid[: mask.shape[0], : mask.shape[1]]
    a = ndimage.sum(mask, lab, idx)
    mx, my = ndimage.sum(xx, lab, idx) / a, ndimage.sum(yy, lab, idx) / a
    sxx = ndimage.sum(xx * xx, lab, idx) / a - mx * mx
    syy = ndimage.sum(yy * yy, lab, idx) / a - my * my
    sxy = ndimage.sum(xx * yy, lab, idx) / a - mx * my
    out = np.zeros((len(ref), 3))
    for i in range(len(ref)):
        dx, dy = row.get(f"m{i:03d}_dx_px", ""), row.get(f"m{i:03d}_dy_px", "")
        if dx == "" or dy == "":
            continue
        p = ref[i] + [float(dx), float(dy)]
        j = np.argmin((mx - p[0]) ** 2 + (my - p[1]) ** 2)
        if (mx[j] - p[0]) ** 2 + (my[j] - p[1]) ** 2 <= 4:
            out[i] = [sxx[j] - syy[j], 2 * sxy[j], sxx[j] + syy[j]]
    return out.ravel()


if __name__ == "__main__":
    root = os.path.dirname(os.path.abspath(__file__))
    shared = os.environ.get("VISUOTACT_SHARED", os.path.join(root, "..", "..", "shared"))
    work = os.path.join(os.environ.get("PEER_WORK", "/tmp/visuotact-peers"), "tactip127")
    main(
        os.path.join(shared, "reference", "real", "tactip127_surface"),
        os.path.join(work, "features.csv"),
        os.path.join(work, "sensor.json"),
    )

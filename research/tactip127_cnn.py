"""A convolutional network on the real 127-pin TacTip frames themselves, beside visuotact.

The learner the data set's lab uses for such frames (a CNN on the whole image, no pins found),
trained on the data set's own train/test split: the frames scaled to SIZE x SIZE (default 128),
five conv 3x3 + batch-norm + ReLU + max-pool blocks (32, 32, 64, 64, 64 channels), a 256-unit
layer, the four standardised targets; Adam with a cosine schedule over EPOCHS (default 30),
batches of 64, the epoch with the lowest error on a tenth of the training frames held out kept.
Prints the test mean absolute error per target after every epoch and at the end, then the
correlation of its errors with visuotact's (the estimates `scripts/bench/real-tactip127` wrote): two
learners that read the frames differently failing on the same frames is what a limit in the
frames looks like. Seeded; about a minute an epoch on 2 cores at 128 x 128.

Usage (after scripts/bench/real-tactip127; needs torch, e.g. the venv scripts/ci/lerobot-test makes):
    target/lerobot-venv/bin/python research/tactip127_cnn.py
"""

import csv
import os
import time

import numpy as np
import torch
from PIL import Image
from torch import nn

TARGETS = ["pose_2", "pose_6", "move_1", "move_6"]


def labels(path):
    rows = list(csv.DictReader(open(path)))
    return [r["image_name"] for r in rows], np.array([[float(r[t]) for t in TARGETS] for r in rows], np.float32)


def frames(data, names, size, cache):
    if os.path.exists(cache):
        return np.load(cache)
    x = np.stack(
        [
            np.asarray(Image.open(os.path.join(data, "frames", n)).convert("L").resize((size, size), Image.BILINEAR))
            for n in names
        ]
    )
    np.save(cache, x)
    return x


def network(size):
    def block(c_in, c_out):
        return [nn.Conv2d(c_in, c_out, 3, padding=1), nn.BatchNorm2d(c_out), nn.ReLU(), nn.MaxPool2d(2)]

    channels = [1, 32, 32, 64, 64, 64] if size >= 128 else [1, 32, 32, 64, 64]
    layers = [layer for a, b in zip(channels, channels[1:]) for layer in block(a, b)]
    side = size >> (len(channels) - 1)
    return nn.Sequential(
        *layers,
        nn.Flatten(),
        nn.Dropout(0.1),
        nn.Linear(channels[-1] * side * side, 256),
        nn.ReLU(),
        nn.Dropout(0.1),
        nn.Linear(256, len(TARGETS)),
    )


def main():
    root = os.path.dirname(os.path.abspath(__file__))
    shared = os.environ.get("VISUOTACT_SHARED", os.path.join(root, "..", "..", "shared"))
    data = os.path.join(shared, "reference", "real", "tactip127_surface")
    work = os.path.join(os.environ.get("PEER_WORK", "/tmp/visuotact-peers"), "tactip127")
    size = int(os.environ.get("SIZE", "128"))
    epochs = int(os.environ.get("EPOCHS", "30"))
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    os.makedirs(work, exist_ok=True)

    train_names, y_train = labels(os.path.join(data, "train_targets.csv"))
    test_names, y_test = labels(os.path.join(data, "test_targets.csv"))
    x = frames(data, train_names + test_names, size, os.path.join(work, f"frames_{size}.npy"))
    x = torch.tensor(x[:, None].astype(np.float32) / 255.0)
    n_train = len(train_names)
    mean, std = y_train.mean(0), y_train.std(0)
    y = torch.tensor((np.concatenate([y_train, y_test]) - mean) / std)
    order = rng.permutation(n_train)
    held, fit = order[: n_train // 10], order[n_train // 10 :]
    test = np.arange(n_train, len(x))

    net = network(size)
    opt = torch.optim.Adam(net.parameters(), 1e-3, weight_decay=1e-5)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)

    def estimate(idx):
        net.eval()
        with torch.no_grad():
            return torch.cat([net(x[idx[k : k + 256]]) for k in range(0, len(idx), 256)])

    def test_mae():
        p = estimate(test).numpy() * std + mean
        return p, np.abs(p - y_test).mean(0)

    best, kept = float("inf"), None
    t0 = time.time()
    for epoch in range(epochs):
        net.train()
        shuffled = rng.permutation(fit)
        for k in range(0, len(shuffled), 64):
            b = shuffled[k : k + 64]
            opt.zero_grad()
            loss = ((net(x[b]) - y[b]) ** 2).mean()
            loss.backward()
            opt.step()
        schedule.step()
        held_mse = ((estimate(held) - y[held]) ** 2).mean().item()
        if held_mse < best:
            best, kept = held_mse, {k: t.clone() for k, t in net.state_dict().items()}
        _, mae = test_mae()
        print(
            f"epoch {epoch + 1} ({time.time() - t0:.0f} s): held-out mse {held_mse:.4f} (scaled), test "
            + " ".join(f"{t}={m:.4f}" for t, m in zip(TARGETS, mae)),
            flush=True,
        )
    net.load_state_dict(kept)
    p, mae = test_mae()
    print(f"CNN on {size} x {size} frames, best held-out epoch: " + " ".join(f"{t}={m:.4f}" for t, m in zip(TARGETS, mae)))

    ours = os.path.join(work, "p.csv")
    if not os.path.exists(ours):
        print(f"no {ours}: run scripts/bench/real-tactip127 first for the comparison with visuotact")
        return
    rows = {r["frame"].split("/")[-1]: r for r in csv.DictReader(open(ours))}
    v = np.array([[float(rows[n][t]) for t in TARGETS] for n in test_names])
    print("visuotact: " + " ".join(f"{t}={m:.4f}" for t, m in zip(TARGETS, np.abs(v - y_test).mean(0))))
    print("mean of the two: " + " ".join(f"{t}={m:.4f}" for t, m in zip(TARGETS, np.abs((v + p) / 2 - y_test).mean(0))))
    corr = [np.corrcoef(v[:, i] - y_test[:, i], p[:, i] - y_test[:, i])[0, 1] for i in range(len(TARGETS))]
    print("correlation of the CNN's errors with visuotact's: " + " ".join(f"{t}={c:.2f}" for t, c in zip(TARGETS, corr)))


if __name__ == "__main__":
    main()

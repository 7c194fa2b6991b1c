#!/usr/bin/env python3
"""Marker tracking on the real GelSight Mini videos, visuotact beside the OpenCV peer.

There is no ground truth for real frames; the reference is the vendor tracker's own per-frame
positions (`marker_locations_N.csv`: frame, row, col, Ox, Oy, Cx, Cy in pixels, frame 1
being the video's first frame). Each tracker's markers are paired with the vendor's markers
nearest at the first frame (within half the pitch); per frame and paired marker the tracker
either reports a position or not, and a reported one is compared with the vendor's.

- visuotact: `calibrate VIDEO --first 5 --keep-border` and `extract` with its defaults (the
  driver, scripts/bench/peers-tracking-real, runs them); a marker is reported when its cells are filled;
- visuotact followed: the same sensor file, `extract --temporal` (each frame tracked from the
  last one's positions, as `run --temporal` live), when a second features file is given;
- peer NN: the OpenCV peer's blobs (../shared/peers/opencv_pipeline.py `process` on the inverted
  frame: dark markers) of the first frame are the markers, each taking the nearest blob within
  half a pitch in every frame (scripts/bench/peers_tracking.py's rule).

Usage: peers_tracking_real.py SHARED_PEERS VIDEO MARKERS_CSV SENSOR_JSON FEATURES_CSV [FOLLOWED_CSV]
The vendor's positions are not truth: in some frames of video 5 they repeat the previous
frame's exactly while the gel moves (its tracker held stale positions), and the videos carry
that tracker's drawing (red arrows and crosses, dark in luma, across the markers). The last three
columns count those frames and score without them. `unreported under the drawing` counts the
vendor marker-frames a tracker left without a position where at least a fifth of the dot's disc
at the vendor's position is the drawing's red (saturated red pixels, R over 1.4 × G and B and
over 90): there the dot is hidden or broken by the burned-in drawing, not by the gel.

Prints one Markdown row per tracker.
"""
import csv
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peers_tracking import pitch_of, read_rows  # noqa: E402


def vendor_positions(path):
    frames = {}
    for line in open(path):
        f, row, col, _ox, _oy, cx, cy = (float(v) for v in line.split(","))
        f, row, col = int(f), int(row), int(col)
        frames.setdefault(f - 1, {})[(row, col)] = (cx, cy)
    keys = sorted(frames[0])
    return keys, {f: np.array([d.get(k, (np.nan, np.nan)) for k in keys], float)
                  for f, d in frames.items()}


def frozen_frames(vendor):
    """Frames where the vendor's positions repeat the previous frame's exactly while the gel is
    displaced (over 1 px from the first frame): its tracker held stale positions there."""
    fs = sorted(vendor)
    return {b for a, b in zip(fs, fs[1:])
            if np.nanmax(np.abs(vendor[b] - vendor[a])) == 0
            and np.nanmax(np.abs(vendor[b] - vendor[fs[0]])) > 1}


def red_of(img):
    """Where a BGR frame shows the drawing's saturated red."""
    b, g, r = (img[..., k].astype(int) for k in range(3))
    return (r > 1.4 * g) & (r > 1.4 * b) & (r > 90)


def drawn_over(reds, vendor, radius_px):
    """Per frame, whether each vendor marker's dot (a disc of `radius_px` at the vendor's
    position, its part inside the image) is at least a fifth the drawing's red."""
    out = {}
    for f, red in enumerate(reds):
        if f not in vendor:
            continue
        h, w = red.shape
        hidden = np.zeros(len(vendor[f]), bool)
        for j, (x, y) in enumerate(vendor[f]):
            if np.isnan(x):
                continue
            # The disc's bounding window, clipped to the image.
            x0, x1 = max(int(np.floor(x - radius_px)), 0), min(int(np.ceil(x + radius_px)) + 1, w)
            y0, y1 = max(int(np.floor(y - radius_px)), 0), min(int(np.ceil(y + radius_px)) + 1, h)
            if x0 >= x1 or y0 >= y1:
                continue
            yy, xx = np.mgrid[y0:y1, x0:x1]
            disc = (xx - x) ** 2 + (yy - y) ** 2 <= radius_px ** 2
            hidden[j] = disc.any() and red[y0:y1, x0:x1][disc].mean() >= 0.2
        out[f] = hidden
    return out


def score(name, ref_xy, tracks, keys, vendor, drawn):
    pitch = pitch_of(vendor[0])
    d = np.hypot(ref_xy[:, None, 0] - vendor[0][None, :, 0], ref_xy[:, None, 1] - vendor[0][None, :, 1])
    near = d.argmin(axis=0)
    paired = d[near, np.arange(len(keys))] < 0.5 * pitch
    seen = reported = under_drawing = 0
    dist = []
    live = []
    frozen = frozen_frames(vendor)
    for f, v in vendor.items():
        if f not in tracks:
            continue
        for j in np.flatnonzero(paired):
            if np.isnan(v[j, 0]):
                continue
            seen += 1
            p = tracks[f][near[j]]
            if np.isnan(p[0]):
                under_drawing += int(drawn[f][j])
                continue
            reported += 1
            dist.append(np.hypot(*(p - v[j])))
            if f not in frozen:
                live.append(dist[-1])
    dist = np.array(dist)
    live = np.array(live)
    return (f"| {name} | {int(paired.sum())}/{len(keys)} | {seen} | {reported} ({100 * reported / max(seen, 1):.1f} %) "
            f"| {dist.mean():.2f} ({np.median(dist):.3f}) | {np.percentile(dist, 95):.2f} | {int((dist > 3).sum())} "
            f"| {len(frozen)} | {live.mean():.2f} | {int((live > 10).sum())} "
            f"| {seen - reported} ({under_drawing}) |")


def positions_from_features(ref, features):
    """Per frame, each marker's position (the sensor file's plus the displacement; NaN where
    its cells are empty)."""
    out = {}
    for r in read_rows(features):
        f = int(r["frame"].split("#")[-1])
        p = np.full((len(ref), 2), np.nan)
        for k in range(len(ref)):
            dx, dy = r.get(f"m{k:03d}_dx_px", ""), r.get(f"m{k:03d}_dy_px", "")
            if dx != "" and dy != "":
                p[k] = ref[k] + (float(dx), float(dy))
        out[f] = p
    return out


def main():
    peers, video, markers, sensor, features = sys.argv[1:6]
    followed = sys.argv[6] if len(sys.argv) > 6 else None
    sys.path.insert(0, peers)
    import cv2
    import opencv_pipeline as op
    cv2.setNumThreads(1)
    keys, vendor = vendor_positions(markers)
    # visuotact: positions are the sensor file's markers plus the displacements.
    cal = json.load(open(sensor))
    ref = np.array([(m["x_px"], m["y_px"]) for m in cal["markers"]])
    vt = positions_from_features(ref, features)
    # The peer: blobs of every frame, nearest-blob tracking from the first frame's blobs.
    cap = cv2.VideoCapture(video)
    blobs = []
    reds = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        reds.append(red_of(img))
        _, stats, cents, _ = op.process(255 - img, "tactile")
        blobs.append(cents[stats[:, 4] >= 5])
    peer_ref = blobs[0]
    pitch = pitch_of(peer_ref)
    peer = {}
    for f, b in enumerate(blobs):
        d = np.hypot(peer_ref[:, None, 0] - b[None, :, 0], peer_ref[:, None, 1] - b[None, :, 1])
        j = d.argmin(axis=1)
        ok = d[np.arange(len(peer_ref)), j] < 0.5 * pitch
        p = np.full((len(peer_ref), 2), np.nan)
        p[ok] = b[j[ok]]
        peer[f] = p
    # The dot's radius: the sensor file's median marker area as a disc.
    radius_px = float(np.sqrt(np.median([m["area_px"] for m in cal["markers"]]) / np.pi))
    drawn = drawn_over(reds, vendor, radius_px)
    name = os.path.basename(video)
    print(score(f"visuotact ({name})", ref, vt, keys, vendor, drawn))
    if followed:
        vt_followed = positions_from_features(ref, followed)
        print(score(f"visuotact followed ({name})", ref, vt_followed, keys, vendor, drawn))
    print(score(f"peer NN ({name})", peer_ref, peer, keys, vendor, drawn))


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Marker tracking against the simulator's truth: visuotact beside the OpenCV peer.

For each case folder (written by scripts/bench/peers-tracking) holding a simulated `session/`, the
sensor file `visuotact.json` that `visuotact calibrate` made from its reference frames and the
feature table `visuotact.csv` that `visuotact extract` made from its frames, three trackers are
scored with one rule, the one of `visuotact check-tracking`:

- visuotact: a marker is reported when its displacement cells are filled;
- peer NN: the OpenCV peer's blobs (../shared/peers/opencv_pipeline.py `process`, on the inverted
  image when the markers are darker than the skin) in the first reference frame are the markers;
  in each frame every marker takes the blob nearest its reference position, if nearer than half
  the pitch (the median nearest-neighbour distance of the reference blobs);
- peer Hungarian: the same blobs, assigned to the markers at least total squared distance
  (scipy's linear_sum_assignment), pairs farther than one pitch dropped.

Each tracker's markers are paired with the simulated marker nearest at rest (within half its
pitch). Per frame and marker: a marker the simulator calls visible that is not reported is lost
(visible markers no tracker marker stands for count as lost too: `uncalibrated`); a reported
marker nearer another marker's true position than its own, or off its own by over half the pitch,
has a wrong identity; the displacement error is |(measured - reference) - (true - true at rest)|
over the visible markers reported with the right identity.

Usage: peers_tracking.py SHARED_PEERS CASE...   (prints a Markdown table)
"""
import csv
import json
import os
import re
import sys

import numpy as np


def read_rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def truth_by_frame(session):
    """frame name -> (xy array, visible bool array), in the simulator's marker order."""
    frames = {}
    for r in read_rows(os.path.join(session, "truth.csv")):
        frames.setdefault(r["frame"], []).append(
            (float(r["x_px"]), float(r["y_px"]), r["visible"] == "1"))
    return {k: (np.array([(x, y) for x, y, _ in v]), np.array([vis for _, _, vis in v]))
            for k, v in frames.items()}


def touch_frames(session):
    return [r["frame"] for r in read_rows(os.path.join(session, "frames.csv"))
            if r["kind"] == "touch"]


def reference_frames(session):
    return [r["frame"] for r in read_rows(os.path.join(session, "frames.csv"))
            if r["kind"] == "reference"]


def pitch_of(xy):
    d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    np.fill_diagonal(d, np.inf)
    return float(np.median(d.min(axis=1)))


class Score:
    def __init__(self, name):
        self.name = name
        self.cases = 0
        self.calibrated = 0
        self.uncalibrated = 0
        self.visible = 0
        self.lost = 0
        self.wrong = 0
        self.errs = []

    def add_case(self, ref_xy, pitch, rest_xy, rest_vis, frames, tracks):
        """ref_xy: the tracker's markers at rest; tracks: frame -> (N, 2) displacements, NaN
        where a marker is not reported."""
        self.cases += 1
        self.calibrated += len(ref_xy)
        d = np.hypot(ref_xy[:, None, 0] - rest_xy[None, :, 0],
                     ref_xy[:, None, 1] - rest_xy[None, :, 1])
        near = d.argmin(axis=1)
        paired = d[np.arange(len(ref_xy)), near] < 0.5 * pitch
        taken = np.zeros(len(rest_xy), bool)
        taken[near[paired]] = True
        self.uncalibrated += int((rest_vis & ~taken).sum())
        for name, (now_xy, now_vis) in frames.items():
            disp = tracks[name]
            for i in np.flatnonzero(paired):
                t = near[i]
                visible = now_vis[t]
                self.visible += int(visible)
                if np.isnan(disp[i, 0]):
                    self.lost += int(visible)
                    continue
                p = ref_xy[i] + disp[i]
                dist = np.hypot(now_xy[:, 0] - p[0], now_xy[:, 1] - p[1])
                own = dist[t]
                if (np.delete(dist, t) < own).any() or own > 0.5 * pitch:
                    self.wrong += 1
                    continue
                if visible:
                    true_disp = now_xy[t] - rest_xy[t]
                    self.errs.append(float(np.hypot(*(disp[i] - true_disp))))

    def row(self, label):
        e = np.sort(np.array(self.errs)) if self.errs else np.array([np.nan])
        p99 = e[int(round((len(e) - 1) * 0.99))]
        lost = self.lost + self.uncalibrated
        return (f"| {label} | {self.name} | {self.calibrated // max(self.cases, 1)} | {self.visible} "
                f"| {lost} ({100.0 * lost / max(self.visible, 1):.2f} %) | {self.wrong} "
                f"| {np.mean(e):.3f} | {p99:.3f} |")


def visuotact_tracks(case, frames):
    sensor = json.load(open(os.path.join(case, "visuotact.json")))
    ref_xy = np.array([(m["x_px"], m["y_px"]) for m in sensor["markers"]])
    rows = {r["frame"]: r for r in read_rows(os.path.join(case, "visuotact.csv"))}
    tracks = {}
    for name in frames:
        r = rows[name]
        disp = np.full((len(ref_xy), 2), np.nan)
        for k in range(len(ref_xy)):
            dx, dy = r.get(f"m{k:03d}_dx_px", ""), r.get(f"m{k:03d}_dy_px", "")
            if dx != "" and dy != "":
                disp[k] = (float(dx), float(dy))
        tracks[name] = disp
    return ref_xy, float(sensor["pitch_px"]), tracks


def peer_blobs(op, path, dark):
    import cv2
    img = cv2.imread(path, cv2.IMREAD_COLOR)
    if dark:
        img = 255 - img
    _, stats, cents, _ = op.process(img, "tactile")
    keep = stats[:, 4] >= 5          # visuotact's smallest marker area
    return cents[keep]


def peer_tracks(op, session, frames, dark, hungarian):
    from scipy.optimize import linear_sum_assignment
    ref = reference_frames(session)[0]
    ref_xy = peer_blobs(op, os.path.join(session, "reference", ref), dark)
    pitch = pitch_of(ref_xy)
    tracks = {}
    for name in frames:
        blobs = peer_blobs(op, os.path.join(session, "frames", name), dark)
        disp = np.full((len(ref_xy), 2), np.nan)
        if len(blobs):
            d = np.hypot(ref_xy[:, None, 0] - blobs[None, :, 0],
                         ref_xy[:, None, 1] - blobs[None, :, 1])
            if hungarian:
                rows, cols = linear_sum_assignment(d ** 2)
                ok = d[rows, cols] < pitch
                rows, cols = rows[ok], cols[ok]
            else:
                rows = np.arange(len(ref_xy))
                cols = d.argmin(axis=1)
                ok = d[rows, cols] < 0.5 * pitch
                rows, cols = rows[ok], cols[ok]
            disp[rows] = blobs[cols] - ref_xy[rows]
        tracks[name] = disp
    return ref_xy, pitch, tracks


def main():
    peers, cases = sys.argv[1], sys.argv[2:]
    sys.path.insert(0, peers)
    import opencv_pipeline as op
    import cv2
    cv2.setNumThreads(1)
    by_sensor = {}
    for case in cases:
        session = os.path.join(case, "session")
        meta = json.load(open(os.path.join(session, "session.json")))
        look = meta["config"]["look"]
        luma = lambda c: 0.2989 * c[0] + 0.5870 * c[1] + 0.1140 * c[2]
        dark = luma(look["marker"]) < luma(look["background"])
        truth = truth_by_frame(session)
        rest_xy, rest_vis = truth[reference_frames(session)[0]]
        names = touch_frames(session)
        frames = {n: truth[n] for n in names}
        label = f"{meta['sensor']} {meta['protocol']}"
        scores = by_sensor.setdefault(label, [Score("visuotact"), Score("peer NN"),
                                              Score("peer Hungarian")])
        ref_xy, pitch, tracks = visuotact_tracks(case, names)
        scores[0].add_case(ref_xy, pitch, rest_xy, rest_vis, frames, tracks)
        for s, hungarian in ((scores[1], False), (scores[2], True)):
            ref_xy, pitch, tracks = peer_tracks(op, session, names, dark, hungarian)
            s.add_case(ref_xy, pitch, rest_xy, rest_vis, frames, tracks)
        print(f"scored {case}", file=sys.stderr)
    print("| sensor, protocol | tracker | markers | visible marker-frames | lost | wrong identity "
          "| mean error px | p99 error px |")
    print("|---|---|---|---|---|---|---|---|")
    for label, scores in by_sensor.items():
        for s in scores:
            print(s.row(label))


if __name__ == "__main__":
    main()

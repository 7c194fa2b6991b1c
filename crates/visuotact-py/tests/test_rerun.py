"""Rerun recordings written by `visuotact export rerun` and `run --rerun`, read back by the
`rerun-sdk` Python package (the version of the `rerun` crate that wrote them, 0.24.1) with
its dataframe API.

Every frame of the session must be on the `frame` timeline, and the values must equal the
session's tables: each estimate (float64, exact), each marker's position (reference +
displacement, float32: 1e-3 px) with its colour by status, each force sample on the
`capture_time` timeline (exact).
"""

import csv
import json
import os
import subprocess

import pytest
import rerun as rr

BIN = os.environ.get("VISUOTACT_BIN", "visuotact")
NS = "/cone"
AXES = ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"]
FOUND = [40, 200, 80]


def cli(*args):
    subprocess.run([BIN, *map(str, args)], check=True, capture_output=True)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A simulated cone press (frames, force.csv), its features, and an estimates table made
    up here (export copies tables, so any values do)."""
    d = tmp_path_factory.mktemp("rerun")
    s = d / "session"
    cli("simulate", "--sensor", "cone", "--protocol", "press", "--duration-s", "1",
        "--references", "2", "--force-rate-hz", "200", "-o", s)
    cli("calibrate", s / "reference", "-o", d / "sensor.json")
    cli("extract", "--sensor", d / "sensor.json", s / "frames", "-o", s / "features.csv")
    with open(s / "estimates.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["frame", "x_mm", "y_mm", "depth_mm", "fz_n", "flags"])
        for k, r in enumerate(rows(s / "frames.csv")):
            w.writerow([r["frame"], 1.5 + k, -2.0 * k, 0.25 * k, 0.1 * k + 1e-7, ""])
    return d, s


def table(path, index):
    rec = rr.dataframe.load_recording(str(path))
    return rec.view(index=index, contents="/**").select().read_all().to_pylist()


def one(row, column):
    """The single scalar of a Scalars cell, or None."""
    cell = row.get(column)
    return None if cell is None else cell[0]


def test_exported_session_reads_back_in_rerun_sdk(session):
    d, s = session
    out = d / "session.rrd"
    cli("export", "rerun", s, "-o", out, "--namespace", NS, "--sensor", d / "sensor.json")
    frames = rows(s / "frames.csv")
    est = {r["frame"]: r for r in rows(s / "estimates.csv")}
    feats = {r["frame"]: r for r in rows(s / "features.csv")}
    markers = json.loads((d / "sensor.json").read_text())["markers"]

    by_frame = {r["frame"]: r for r in table(out, "frame") if r["frame"] is not None}
    assert sorted(by_frame) == list(range(len(frames)))
    checked_points = 0
    for k, f in enumerate(frames):
        r = by_frame[k]
        e = est[f["frame"]]
        for name in ["x_mm", "y_mm", "depth_mm", "fz_n"]:
            assert one(r, f"{NS}/estimate/{name}:Scalars:scalars") == float(e[name]), (k, name)
        if f["frame"] not in feats:
            continue
        row = feats[f["frame"]]
        pos = r[f"{NS}/image/markers:Points2D:positions"]
        colours = r[f"{NS}/image/markers:Points2D:colors"]
        assert len(pos) == len(markers)
        for m, p, c in zip(markers, pos, colours):
            dx, dy = float(row[f"m{m['id']:03d}_dx_px"]), float(row[f"m{m['id']:03d}_dy_px"])
            assert abs(p[0] - (m["x_px"] + dx)) <= 1e-3 and abs(p[1] - (m["y_px"] + dy)) <= 1e-3
            assert [(c >> 24) & 255, (c >> 16) & 255, (c >> 8) & 255] == FOUND
            checked_points += 1
        assert one(r, f"{NS}/health/found:Scalars:scalars") == float(row["n_found"])
        assert r[f"{NS}/image:EncodedImage:blob"] is not None
    assert checked_points >= 2 * len(feats)

    # The force sensor: every sample at its own capture time, none on the frame timeline.
    force = rows(s / "force.csv")
    start = json.loads((s / "session.json").read_text()).get("started_unix_s") or 0.0
    by_time = {}
    for r in table(out, "capture_time"):
        if one(r, f"{NS}/force/fz_n:Scalars:scalars") is not None:
            by_time[r["capture_time"]] = r
    assert len(by_time) == len(force)
    for f, (t, r) in zip(force, sorted(by_time.items())):
        assert abs(t.timestamp() - (start + float(f["timestamp_s"]))) <= 2e-6
        for a in AXES:
            assert one(r, f"{NS}/force/{a}:Scalars:scalars") == float(f[a])


def test_live_run_into_a_recording(session):
    d, _ = session
    out = d / "live.rrd"
    cli("run", "--source", "sim:cone", "--sensor", d / "sensor.json", "--max-frames", "8",
        "--unpaced", "--quiet", "--rerun", out, "--rerun-images", "--slip", "builtin")
    t = [r for r in table(out, "frame") if r["frame"] is not None]
    assert [r["frame"] for r in t] == list(range(8))
    for r in t:
        assert one(r, "/visuotact/contact:Scalars:scalars") in (0.0, 1.0)
        assert 0.0 <= one(r, "/visuotact/slip:Scalars:scalars") <= 1.0
        assert one(r, "/visuotact/slip/state:Scalars:scalars") in (0.0, 1.0, 2.0)
        assert one(r, "/visuotact/health/found:Scalars:scalars") >= 1
        assert r["/visuotact/image:EncodedImage:blob"] is not None
        assert r["/visuotact/image/markers:Points2D:positions"]

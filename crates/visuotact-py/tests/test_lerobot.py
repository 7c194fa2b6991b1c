"""LeRobot v3.0 data sets written by `visuotact export lerobot`, read back the way LeRobot
reads them: Parquet through `pyarrow` and through Hugging Face `datasets` with the features
LeRobot derives from `meta/info.json` (its `get_hf_features_from_features`), tasks through
`pandas` (the task text is the index), the video through `ffprobe`; every field of
`meta/info.json` and of the episodes table that LeRobot's loader reads is checked."""

import csv
import json
import math
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

BIN = os.environ.get("VISUOTACT_BIN", "visuotact")
KEY = "observation.images.tactile"
AXES = ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"]


def cli(*args):
    return subprocess.run([BIN, *map(str, args)], check=True, capture_output=True, text=True)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def num(x):
    return float(x) if x not in ("", "NaN") else math.nan


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Two simulated cone presses (frames, force.csv, features, a made-up estimates table),
    exported as two episodes."""
    d = tmp_path_factory.mktemp("lerobot")
    sessions = []
    for seed in (1, 2):
        s = d / f"s{seed}"
        cli("simulate", "--sensor", "cone", "--protocol", "press", "--duration-s", "0.8",
            "--references", "2", "--force-rate-hz", "200", "--seed", seed, "-o", s)
        if seed == 1:
            cli("calibrate", s / "reference", "-o", d / "sensor.json")
        cli("extract", "--sensor", d / "sensor.json", s / "frames", "-o", s / "features.csv")
        with open(s / "estimates.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["frame", "fz_n", "depth_mm", "flags"])
            for k, r in enumerate(rows(s / "frames.csv")):
                w.writerow([r["frame"], 0.5 * k + seed, 0.1 * k, ""])
        sessions.append(s)
    out = d / "ds"
    cli("export", "lerobot", *sessions, "-o", out, "--task", "press the cone",
        "--robot-type", "visuotact-sim")
    return out, sessions


def test_info_json_has_what_lerobot_reads(dataset):
    out, sessions = dataset
    info = json.loads((out / "meta/info.json").read_text())
    n = sum(len(rows(s / "frames.csv")) for s in sessions)
    assert info["codebase_version"] == "v3.0"
    assert (info["total_episodes"], info["total_frames"], info["total_tasks"]) == (2, n, 1)
    assert info["splits"] == {"train": "0:2"} and info["fps"] == 25
    assert info["robot_type"] == "visuotact-sim"
    for k in ("chunks_size", "data_files_size_in_mb", "video_files_size_in_mb"):
        assert isinstance(info[k], int) and info[k] > 0
    assert (out / info["data_path"].format(chunk_index=0, file_index=0)).is_file()
    assert (out / info["video_path"].format(video_key=KEY, chunk_index=0, file_index=0)).is_file()
    ft = info["features"]
    for k in ("timestamp", "frame_index", "episode_index", "index", "task_index"):
        assert ft[k]["shape"] == [1] and ft[k]["names"] is None
    assert ft["timestamp"]["dtype"] == "float32" and ft["index"]["dtype"] == "int64"
    assert ft["observation.force"]["names"] == AXES
    assert ft["observation.tactile.estimate"]["names"] == ["fz_n", "depth_mm"]
    names = ft["observation.tactile.features"]["names"]
    assert len(names) == ft["observation.tactile.features"]["shape"][0] and "timestamp_s" not in names
    for k, f in ft.items():
        assert "/" not in k
        if f["dtype"] != "video":
            assert f["names"] is None or len(f["names"]) == f["shape"][0], k
    v = ft[KEY]
    assert v["dtype"] == "video" and v["names"] == ["height", "width", "channels"]
    assert v["shape"] == [v["info"]["video.height"], v["info"]["video.width"], 3]
    assert v["info"]["video.codec"] == "av1" and v["info"]["video.fps"] == 25


def test_data_reads_in_pyarrow_and_equals_the_session_tables(dataset):
    out, sessions = dataset
    info = json.loads((out / "meta/info.json").read_text())
    t = pq.read_table(out / "data/chunk-000/file-000.parquet").to_pydict()
    n = info["total_frames"]
    assert t["index"] == list(range(n))
    k = 0
    for e, s in enumerate(sessions):
        frames = rows(s / "frames.csv")
        feats = {r["frame"]: r for r in rows(s / "features.csv")}
        force = rows(s / "force.csv")
        ft = np.array([float(r["timestamp_s"]) for r in force])
        names = info["features"]["observation.tactile.features"]["names"]
        for i, f in enumerate(frames):
            assert (t["episode_index"][k], t["frame_index"][k], t["task_index"][k]) == (e, i, 0)
            assert t["timestamp"][k] == pytest.approx(i / 25, abs=1e-6)
            assert t["observation.tactile.capture_time_s"][k] == float(f["timestamp_s"])
            got = t["observation.tactile.features"][k]
            want = [num(feats[f["frame"]][c]) if f["frame"] in feats else math.nan for c in names]
            for g, w in zip(got, want):
                assert (math.isnan(g) and math.isnan(w)) or g == pytest.approx(w, rel=1e-6, abs=1e-6)
            for a, g in zip(AXES, t["observation.force"][k]):
                w = np.interp(float(f["timestamp_s"]), ft, [float(r[a]) for r in force],
                              left=math.nan, right=math.nan)
                assert (math.isnan(g) and math.isnan(w)) or g == pytest.approx(w, rel=1e-6, abs=1e-9)
            k += 1
    assert k == n


def test_data_loads_in_hf_datasets_with_lerobot_features(dataset):
    """LeRobot loads the data with `Dataset.from_parquet(path, features=…)`, the features built
    from info.json: a Value for shape (1,), a fixed-length sequence for a vector."""
    import datasets

    out, _ = dataset
    info = json.loads((out / "meta/info.json").read_text())
    fixed = getattr(datasets, "List", None)
    hf = {}
    for k, f in info["features"].items():
        if f["dtype"] == "video":
            continue
        if f["shape"] == [1]:
            hf[k] = datasets.Value(f["dtype"])
        elif fixed is not None:
            hf[k] = fixed(datasets.Value(f["dtype"]), length=f["shape"][0])
        else:
            hf[k] = datasets.Sequence(length=f["shape"][0], feature=datasets.Value(f["dtype"]))
    ds = datasets.Dataset.from_parquet(str(out / "data/chunk-000/file-000.parquet"),
                                       features=datasets.Features(hf))
    assert len(ds) == info["total_frames"]
    row = ds.with_format("numpy")[3]
    assert row["observation.force"].shape == (6,) and row["index"] == 3


def test_episodes_tasks_and_stats(dataset):
    out, sessions = dataset
    ep = pq.read_table(out / "meta/episodes/chunk-000/file-000.parquet").to_pydict()
    lengths = [len(rows(s / "frames.csv")) for s in sessions]
    assert ep["episode_index"] == [0, 1] and ep["length"] == lengths
    assert ep["dataset_from_index"] == [0, lengths[0]]
    assert ep["dataset_to_index"] == [lengths[0], sum(lengths)]
    assert ep["tasks"] == [["press the cone"], ["press the cone"]]
    for c in ("data/chunk_index", "data/file_index", "meta/episodes/chunk_index",
              f"videos/{KEY}/chunk_index", f"videos/{KEY}/file_index"):
        assert ep[c] == [0, 0], c
    assert ep[f"videos/{KEY}/from_timestamp"] == [0.0, lengths[0] / 25]
    assert ep[f"videos/{KEY}/to_timestamp"] == [lengths[0] / 25, sum(lengths) / 25]
    tasks = pd.read_parquet(out / "meta/tasks.parquet")
    assert list(tasks.index) == ["press the cone"] and int(tasks.loc["press the cone"].task_index) == 0

    info = json.loads((out / "meta/info.json").read_text())
    stats = json.loads((out / "meta/stats.json").read_text())
    data = pq.read_table(out / "data/chunk-000/file-000.parquet").to_pydict()
    for k, f in info["features"].items():
        s = stats[k]
        assert set(s) == {"min", "max", "mean", "std", "count"}, k
        if f["dtype"] == "video":
            assert np.array(s["mean"]).shape == (3, 1, 1) and s["count"] == [sum(lengths)]
            assert ep[f"stats/{k}/count"] == [[lengths[0]], [lengths[1]]]
            continue
        x = np.array(data[k], dtype=np.float64).reshape(len(data[k]), -1)
        with np.errstate(all="ignore"):
            want = {"min": np.nanmin(x, 0), "max": np.nanmax(x, 0), "mean": np.nanmean(x, 0),
                    "std": np.nanstd(x, 0)}
        for stat, w in want.items():
            w = np.nan_to_num(w, nan=0.0)
            assert np.allclose(s[stat], w, rtol=1e-5, atol=1e-6), (k, stat)
        assert s["count"] == [sum(lengths)]
        assert f"stats/{k}/mean" in ep


def test_video_has_one_frame_per_row(dataset):
    out, _ = dataset
    info = json.loads((out / "meta/info.json").read_text())
    probe = subprocess.run(
        ["ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0", "-show_entries",
         "stream=codec_name,nb_read_frames,r_frame_rate,width,height,pix_fmt", "-of", "json",
         str(out / f"videos/{KEY}/chunk-000/file-000.mp4")],
        check=True, capture_output=True, text=True)
    s = json.loads(probe.stdout)["streams"][0]
    assert int(s["nb_read_frames"]) == info["total_frames"]
    assert s["r_frame_rate"] == "25/1" and s["codec_name"] == "av1" and s["pix_fmt"] == "yuv420p"
    assert [s["height"], s["width"], 3] == info["features"][KEY]["shape"]


def test_refusals_leave_nothing_behind(dataset, tmp_path):
    out, sessions = dataset
    r = subprocess.run([BIN, "export", "lerobot", sessions[0], "-o", out],
                       capture_output=True, text=True)
    assert r.returncode != 0 and "already exists" in r.stderr
    bare = tmp_path / "bare"
    shutil.copytree(sessions[0], bare)
    shutil.rmtree(bare / "frames")
    r = subprocess.run([BIN, "export", "lerobot", bare, "-o", tmp_path / "x"],
                       capture_output=True, text=True)
    assert r.returncode != 0 and "frame_000000.png" in r.stderr and "--save-frames" in r.stderr
    assert not (tmp_path / "x").exists()
    cli("export", "lerobot", bare, "-o", tmp_path / "y", "--no-video")
    info = json.loads((tmp_path / "y/meta/info.json").read_text())
    assert KEY not in info["features"] and info["video_path"] is None


def test_exports_from_python(dataset, tmp_path):
    """The Python package writes the same data set and a bag, with progress callbacks."""
    import visuotact as vt

    out, sessions = dataset
    seen = []
    s = vt.export_lerobot(sessions, tmp_path / "py", task="press the cone",
                          progress=lambda done, total: seen.append((done, total)))
    assert (s["episodes"], s["fps"]) == (2, 25)
    assert seen[-1] == (s["frames"], s["frames"]) and len(seen) == s["frames"]
    a = pq.read_table(out / "data/chunk-000/file-000.parquet")
    b = pq.read_table(tmp_path / "py/data/chunk-000/file-000.parquet")
    assert a.schema == b.schema and a.num_rows == b.num_rows
    for name in a.column_names:  # NaN-aware: a missing value equals a missing value
        x = np.array(a.column(name).to_pylist(), dtype=np.float64)
        y = np.array(b.column(name).to_pylist(), dtype=np.float64)
        assert np.array_equal(x, y, equal_nan=True), name
    seen.clear()
    m = vt.export_mcap(sessions[0], tmp_path / "s.mcap", namespace="/cone",
                       progress=lambda done, total: seen.append((done, total)))
    assert m["frames"] == len(rows(sessions[0] / "frames.csv")) == seen[-1][0] == seen[-1][1]
    assert m["messages"] > m["frames"]
    with pytest.raises(vt.VisuotactError, match="already exists"):
        vt.export_lerobot(sessions, tmp_path / "py")


def test_a_stopped_export_leaves_nothing_behind(dataset, tmp_path):
    """A progress callback that raises (as Ctrl-C would) stops either export after that frame;
    neither the output nor its temporary name is left, and the export then runs whole."""
    import visuotact as vt

    _, sessions = dataset

    def stop_at_3(done, total):
        if done == 3:
            raise KeyboardInterrupt

    for name, export in [("set", lambda o, cb: vt.export_lerobot(sessions, o, progress=cb)),
                         ("s.mcap", lambda o, cb: vt.export_mcap(sessions[0], o, progress=cb)),
                         ("bag", lambda o, cb: vt.export_mcap(sessions[0], o, progress=cb))]:
        out = tmp_path / name
        with pytest.raises(vt.VisuotactError, match="stopped after 3 frames: nothing written"):
            export(out, stop_at_3)
        assert sorted(p.name for p in tmp_path.iterdir()) == [], name
        assert str(export(out, None)["path"]) == str(out)
        assert out.exists() and not (tmp_path / f"{name}.part~").exists()
        shutil.rmtree(out) if out.is_dir() else out.unlink()

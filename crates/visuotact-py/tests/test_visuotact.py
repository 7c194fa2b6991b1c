"""The Python package against the command line on the same frames, and against scipy.

Needs the package installed (scripts/ci/python-test builds the wheel) and the `visuotact`
binary in VISUOTACT_BIN (scripts/test passes the one cargo built).
"""

import csv
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

import visuotact as vt

BIN = os.environ.get("VISUOTACT_BIN", "visuotact")
TARGETS = ["x_mm", "y_mm", "depth_mm"]


def cli(*args):
    subprocess.run([BIN, *map(str, args)], check=True, capture_output=True)


def read_table(path, skip):
    """A CSV's header and its numeric columns after the first `skip` ones (a text `flags`
    column left out), NaN for blanks."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    keep = [i for i, h in enumerate(rows[0]) if h != "flags"]
    rows = [[r[i] for i in keep] for r in rows]
    header = rows[0]
    values = np.array(
        [[float(v) if v not in ("", "NaN") else np.nan for v in r[skip:]] for r in rows[1:]]
    )
    return header, [r[0] for r in rows[1:]], values


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    d = tmp_path_factory.mktemp("session")
    cli("simulate", "--sensor", "iats", "--protocol", "random", "--touches", 40, "--seed", 3,
        "-o", d / "s")
    cli("calibrate", d / "s" / "reference", "-o", d / "sensor.json")
    cli("extract", "--sensor", d / "sensor.json", d / "s" / "frames", "-o", d / "f.csv")
    cli("train", "--features", d / "f.csv", "--labels", d / "s" / "labels.csv",
        "--targets", ",".join(TARGETS), "--ensemble", 2, "--max-epochs", 30,
        "--sensor", d / "sensor.json", "-o", d / "m.json")
    cli("predict", "--model", d / "m.json", "--features", d / "f.csv", "-o", d / "p.csv")
    return d


def frames_of(d):
    return sorted((d / "s" / "frames").glob("*.png"))


def test_features_are_bit_identical_to_the_cli(session):
    header, ids, table = read_table(session / "f.csv", 7)
    columns = header[7:]
    # Calibrated here from the same reference frames, and loaded from the CLI's file.
    refs = sorted((session / "s" / "reference").glob("*.png"))
    mine = vt.Sensor.calibrate([str(p) for p in refs])
    theirs = vt.Sensor.load(session / "sensor.json")
    assert mine.feature_columns == columns == theirs.feature_columns
    for k, path in enumerate(frames_of(session)):
        assert path.name == ids[k]
        a = mine.extract(str(path)).values
        b = theirs.extract(path).values
        np.testing.assert_array_equal(a, table[k])
        np.testing.assert_array_equal(b, table[k])


def test_a_numpy_frame_equals_its_file(session):
    """The same pixels as an array give the same features as the file."""
    import struct
    import zlib

    path = frames_of(session)[0]
    sensor = vt.Sensor.load(session / "sensor.json")
    # Decode the PNG with the standard library (8-bit RGB, no interlace, as visuotact writes).
    data = path.read_bytes()
    pos, idat, (w, h) = 8, b"", (0, 0)
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        chunk = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h = struct.unpack(">II", chunk[:8])
            assert chunk[8:10] == bytes([8, 2])
        elif kind == b"IDAT":
            idat += chunk
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride = 3 * w
    img = np.zeros((h, stride), np.uint8)
    prev = np.zeros(stride, np.int32)
    for y in range(h):
        f, line = raw[y * (stride + 1)], np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1)
        cur = line.astype(np.int32)
        if f == 1:
            out = np.zeros(stride, np.int32)
            for x in range(stride):
                out[x] = (cur[x] + (out[x - 3] if x >= 3 else 0)) & 255
            cur = out
        elif f == 2:
            cur = (cur + prev) & 255
        elif f == 3:
            out = np.zeros(stride, np.int32)
            for x in range(stride):
                out[x] = (cur[x] + ((out[x - 3] if x >= 3 else 0) + prev[x]) // 2) & 255
            cur = out
        elif f == 4:
            out = np.zeros(stride, np.int32)
            for x in range(stride):
                a = out[x - 3] if x >= 3 else 0
                c = prev[x - 3] if x >= 3 else 0
                b = prev[x]
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                out[x] = (cur[x] + pred) & 255
            cur = out
        img[y] = cur
        prev = cur
    frame = img.reshape(h, w, 3)
    np.testing.assert_array_equal(sensor.extract(frame).values, sensor.extract(str(path)).values)


def test_training_and_prediction_match_the_cli(session):
    header, _, table = read_table(session / "f.csv", 7)
    _, _, labels = read_table(session / "s" / "labels.csv", 1)
    _, _, cli_pred = read_table(session / "p.csv", 1)
    p_header = read_table(session / "p.csv", 1)[0][1:]
    sensor = vt.Sensor.load(session / "sensor.json")
    model = vt.Model.train(table, labels, header[7:], TARGETS, ensemble=2, max_epochs=30,
                           sensor=sensor)
    loaded = vt.Model.load(session / "m.json")
    assert model.to_json() == loaded.to_json()
    for m in (model, loaded):
        est = m.predict(table[:, [header[7:].index(c) for c in m.columns]])
        for j, name in enumerate(p_header):
            if name in est:
                np.testing.assert_allclose(est[name], cli_pred[:, j], rtol=0, atol=1e-12)
        assert (est["filled"] == 0).all()
        # The whole table by its column names, and a Features as it is, give the same.
        by_name = m.predict(table, columns=header[7:])
        np.testing.assert_array_equal(by_name[TARGETS[0]], est[TARGETS[0]])
        first = m.predict(sensor.extract(frames_of(session)[0]))
        np.testing.assert_allclose(first[TARGETS[0]], est[TARGETS[0]][:1], rtol=0, atol=1e-12)
    # The inputs were chosen by cross-validation; the scores travel with the model.
    assert [s["chosen"] for s in model.selection].count(True) == 1
    assert all(s["folds"] >= 1 for s in model.selection)
    assert model.selection == loaded.selection
    with pytest.raises(vt.VisuotactError, match="no column"):
        model.predict(table[:, :3], columns=header[7:10])
    # The live iterator over the same frames gives the same estimates.
    rows = list(vt.live(str(session / "s" / "frames"), model=loaded))
    assert len(rows) == len(cli_pred)
    for r, want in zip(rows, cli_pred):
        got = [r["estimate"][n] for n in p_header]
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
        assert r["slip"] is None
    # With the built-in slip detector: the same estimates, and a slip state on every frame.
    slipping = list(vt.live(str(session / "s" / "frames"), model=loaded, slip="builtin"))
    assert [r["estimate"] for r in slipping] == [r["estimate"] for r in rows]
    assert all(r["slip"]["state"] in ("stick", "incipient", "slip") for r in slipping)
    assert all(0.0 <= r["slip"]["score"] <= 1.0 for r in slipping)
    # Beside the state, the displacement field's ten signals the detector read.
    assert all(len(r["slip"]["field"]) == 10 for r in slipping)
    assert all(np.isfinite(list(r["slip"]["field"].values())).all() for r in slipping)
    assert "shift_pitches" in slipping[0]["slip"]["field"]
    with pytest.raises(vt.VisuotactError, match="nope.json"):
        vt.live(str(session / "s" / "frames"), model=loaded, slip="nope.json")


def test_slip_verdicts_match_the_cli(tmp_path):
    video = Path(__file__).parents[4] / "shared/reference/real/gelsight_slip/videos/nylon_thread/exp_num_1/camera_0.avi"
    if not video.exists():
        pytest.skip(f"{video} absent")
    out = tmp_path / "v.csv"
    cli("slip", "detect", "-q", "-o", out, video)
    row = list(csv.DictReader(open(out)))[0]
    got = vt.slip_detect(str(video))
    assert len(got) == 1
    assert got[0]["slip"] == (row["slip"] == "1")
    assert abs(got[0]["score"] - float(row["score"])) < 1e-4


def test_filtfilt_equals_scipy():
    rng = np.random.default_rng(5)
    # A unit-scale signal: 1e-12 is then ~1e-12 relative (a random walk reaching 20 differs by
    # 1.6e-12 absolute, 8e-14 relative: the same rounding).
    x = np.sin(np.linspace(0, 20, 500)) + 0.3 * rng.normal(size=500)
    b, a = scipy.signal.butter(4, 0.1)
    np.testing.assert_allclose(vt.filtfilt(b, a, x), scipy.signal.filtfilt(b, a, x),
                               rtol=0, atol=1e-12)
    taps = scipy.signal.firwin(31, 0.2)
    np.testing.assert_allclose(vt.filtfilt(taps, np.array([1.0]), x),
                               scipy.signal.filtfilt(taps, [1.0], x), rtol=0, atol=1e-12)


def test_bad_frames_raise_naming_them(tmp_path):
    sensor = vt.Sensor.calibrate([vt.simulate(seed=1), vt.simulate(seed=2)])
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"\x89PNG not really")
    with pytest.raises(vt.VisuotactError, match="broken.png"):
        sensor.extract(str(bad))
    with pytest.raises(vt.VisuotactError, match="640×480"):
        sensor.extract(np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(vt.VisuotactError, match="shape"):
        sensor.extract(np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(vt.VisuotactError, match="preset"):
        vt.Sensor.calibrate([vt.simulate()], preset="nope")
    with pytest.raises(vt.VisuotactError, match="targets must be finite"):
        vt.Model.train(np.zeros((3, 2)), np.full((3, 1), np.nan), ["m000_dx_px", "m000_dy_px"],
                       ["y"])


def test_a_gray_array_and_a_press_give_features():
    rest = [vt.simulate(seed=k) for k in range(2)]
    sensor = vt.Sensor.calibrate(rest, preset="iats")
    f = sensor.extract(vt.simulate(30.0, 22.0, 3.0, seed=9))
    assert f.found == sensor.n_markers == 117
    assert f.dx.shape == (117,) and np.isfinite(f.dx).all()
    assert np.nanmax(np.hypot(f.dx, f.dy)) > 1.0
    assert set(f.status) == {"ok"}


def test_calibration_options_match_the_cli(session, tmp_path):
    refs = sorted((session / "s" / "reference").glob("*.png"))
    opts = dict(threshold=0.4, min_area=12, centroid="weighted", keep_border=True)
    sensor = vt.Sensor.calibrate([str(p) for p in refs], **opts)
    cli("calibrate", session / "s" / "reference", "--threshold", 0.4, "--min-area", 12,
        "--centroid", "weighted", "--keep-border", "-o", tmp_path / "cli.json")
    assert sensor.to_json() == (tmp_path / "cli.json").read_text()
    with pytest.raises(vt.VisuotactError, match="unknown calibration option `tresh`"):
        vt.Sensor.calibrate([str(p) for p in refs], tresh=0.4)
    with pytest.raises(vt.VisuotactError, match="window and offset"):
        vt.Sensor.calibrate([str(p) for p in refs], window=31)

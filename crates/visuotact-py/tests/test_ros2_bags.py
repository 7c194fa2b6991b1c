"""ROS 2 bags written by `visuotact export mcap` and `run --mcap`, read back by two independent
implementations: `mcap` + `mcap-ros2-support` (Foxglove's, decoding with the schemas in the
file) and `rosbags` (decoding with its own ROS 2 Humble type store, from a rosbag2 folder).

Every message must decode, stamps must not go back in time on a topic, the types must be the
standard ROS 2 names, and the values must equal the session's tables: force to 1e-9 N, the
contact to 1e-9 m.
"""

import csv
import os
import subprocess
from pathlib import Path

import pytest
from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

BIN = os.environ.get("VISUOTACT_BIN", "visuotact")
TYPES = {
    "/cone/wrench": "geometry_msgs/msg/WrenchStamped",
    "/cone/ft_sensor/wrench": "geometry_msgs/msg/WrenchStamped",
    "/cone/contact": "geometry_msgs/msg/PointStamped",
    "/cone/markers": "sensor_msgs/msg/PointCloud2",
    "/cone/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}
AXES = ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"]


def cli(*args):
    subprocess.run([BIN, *map(str, args)], check=True, capture_output=True)


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A simulated cone press (frames, force.csv), its features, and an estimates table made
    up here from the labels (export copies tables, so any values do)."""
    d = tmp_path_factory.mktemp("ros")
    s = d / "session"
    cli("simulate", "--sensor", "cone", "--protocol", "press", "--duration-s", "1",
        "--references", "2", "--force-rate-hz", "200", "-o", s)
    cli("calibrate", s / "reference", "-o", d / "sensor.json")
    cli("extract", "--sensor", d / "sensor.json", s / "frames", "-o", s / "features.csv")
    with open(s / "estimates.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["frame", *AXES, "x_mm", "y_mm", "depth_mm", "flags"])
        for k, r in enumerate(rows(s / "frames.csv")):
            w.writerow([r["frame"], *[0.1 * k + i for i in range(6)], 1.5 + k, -2.0 * k,
                        0.25 * k, ""])
    return d, s


def stamp_s(header):
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def check_messages(messages, s):
    """messages: (topic, msgtype, msg) in file order."""
    est = {r["frame"]: r for r in rows(s / "estimates.csv")}
    frames = rows(s / "frames.csv")
    force = rows(s / "force.csv")
    by_topic = {}
    for topic, msgtype, msg in messages:
        assert TYPES[topic] == msgtype, (topic, msgtype)
        by_topic.setdefault(topic, []).append(msg)
    assert set(by_topic) == set(TYPES), set(by_topic)
    for topic, msgs in by_topic.items():
        stamps = [stamp_s(m.header) for m in msgs]
        assert stamps == sorted(stamps), topic
    assert len(by_topic["/cone/wrench"]) == len(frames)
    for f, m in zip(frames, by_topic["/cone/wrench"]):
        e = est[f["frame"]]
        got = [m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
               m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z]
        assert all(abs(g - float(e[a])) <= 1e-9 for g, a in zip(got, AXES)), (got, e)
        assert abs(stamp_s(m.header) - float(f["timestamp_s"])) <= 1e-9
        assert m.header.frame_id == "visuotact"
    for f, m in zip(frames, by_topic["/cone/contact"]):
        e = est[f["frame"]]
        assert abs(m.point.x - float(e["x_mm"]) / 1000) <= 1e-9
        assert abs(m.point.y - float(e["y_mm"]) / 1000) <= 1e-9
        assert abs(m.point.z + float(e["depth_mm"]) / 1000) <= 1e-9
    assert len(by_topic["/cone/ft_sensor/wrench"]) == len(force)
    for r, m in zip(force, by_topic["/cone/ft_sensor/wrench"]):
        assert abs(m.wrench.force.z - float(r["fz_n"])) <= 1e-9
        assert abs(m.wrench.torque.x - float(r["tx_nm"])) <= 1e-9
        assert abs(stamp_s(m.header) - float(r["timestamp_s"])) <= 1e-6
    cloud = by_topic["/cone/markers"][0]
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "dx", "dy", "status"]
    assert len(cloud.data) == cloud.width * cloud.point_step
    image = by_topic["/cone/image/compressed"][0]
    assert image.format == "png" and bytes(image.data[:4]) == b"\x89PNG"
    status = by_topic["/diagnostics"][0].status[0]
    assert status.name == "/cone: markers"


def test_mcap_file_reads_in_mcap_ros2(session):
    d, s = session
    bag = d / "cone.mcap"
    cli("export", "mcap", s, "-o", bag, "--namespace", "/cone", "--sensor", d / "sensor.json")
    msgs = [(m.channel.topic, m.schema.name, m.ros_msg) for m in read_ros2_messages(str(bag))]
    check_messages(msgs, s)


def test_bag_folder_reads_in_rosbags(session):
    d, s = session
    bag = d / "cone_bag"
    cli("export", "mcap", s, "-o", bag, "--namespace", "/cone", "--sensor", d / "sensor.json")
    assert (bag / "metadata.yaml").is_file() and (bag / "cone_bag_0.mcap").is_file()
    store = get_typestore(Stores.ROS2_HUMBLE)
    with AnyReader([Path(bag)], default_typestore=store) as r:
        msgs = [(c.topic, c.msgtype, r.deserialize(raw, c.msgtype)) for c, _, raw in r.messages()]
        counts = {c.topic: c.msgcount for c in r.connections}
    check_messages(msgs, s)
    assert sum(counts.values()) == len(msgs)


def test_live_run_into_a_bag(session):
    d, _ = session
    bag = d / "live.mcap"
    cli("run", "--source", "sim:cone", "--sensor", d / "sensor.json", "--max-frames", "8",
        "--unpaced", "--quiet", "--mcap", bag)
    msgs = list(read_ros2_messages(str(bag)))
    active = [m.ros_msg.data for m in msgs if m.channel.topic == "/visuotact/contact/active"]
    assert len(active) == 8
    assert sum(m.channel.topic == "/visuotact/markers" for m in msgs) == 8
    assert sum(m.channel.topic == "/diagnostics" for m in msgs) == 8


def cloud_points(cloud):
    """(dx, dy, status, dx_mm, dy_mm) per point, the mm ones None without those fields."""
    import struct
    off = {f.name: f.offset for f in cloud.fields}
    data = bytes(cloud.data)
    out = []
    for k in range(cloud.width):
        at = k * cloud.point_step
        f32 = lambda name: struct.unpack_from("<f", data, at + off[name])[0] if name in off else None
        out.append((f32("dx"), f32("dy"), data[at + off["status"]], f32("dx_mm"), f32("dy_mm")))
    return out


def test_a_scaled_sensor_puts_millimetres_in_the_marker_cloud(session):
    """`calibrate --pitch-mm`: the bag's marker cloud (export and live) carries dx_mm, dy_mm
    beside the pixels, equal to them times the sensor's mm per pixel (float32)."""
    import json
    d, s = session
    sensor = d / "sensor_mm.json"
    cli("calibrate", s / "reference", "--pitch-mm", "3.5", "-o", sensor)
    scale = json.loads(sensor.read_text())["scale"]["mm_per_px"]
    bag = d / "scaled.mcap"
    cli("export", "mcap", s, "-o", bag, "--namespace", "/cone", "--sensor", sensor)
    live = d / "scaled_live.mcap"
    cli("run", "--source", "sim:cone", "--sensor", sensor, "--max-frames", "4", "--unpaced",
        "--quiet", "--mcap", live)
    for path, topic in [(bag, "/cone/markers"), (live, "/visuotact/markers")]:
        clouds = [m.ros_msg for m in read_ros2_messages(str(path)) if m.channel.topic == topic]
        assert clouds, path
        moved = 0
        for cloud in clouds:
            names = [f.name for f in cloud.fields]
            assert names == ["x", "y", "z", "dx", "dy", "status", "dx_mm", "dy_mm"], names
            for dx, dy, status, dx_mm, dy_mm in cloud_points(cloud):
                if status == 0:
                    assert abs(dx_mm - dx * scale) <= 1e-6 * max(1.0, abs(dx * scale))
                    assert abs(dy_mm - dy * scale) <= 1e-6 * max(1.0, abs(dy * scale))
                    moved += abs(dx) > 0.1
        assert moved > 0 or path == live, "no marker moved in the press"


def test_killed_run_leaves_a_bag_readable_to_its_last_chunk(session):
    """SIGKILL mid-run: no summary, an unfinished chunk at the end, but every chunk closed
    before it (one per second of stamps) streams back whole — from the bag's temporary name
    (`killed.mcap.part~`): an unfinished bag never takes the name of a whole one."""
    import time
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader

    d, _ = session
    named, bag = d / "killed.mcap", d / "killed.mcap.part~"
    p = subprocess.Popen([BIN, "run", "--source", "sim:cone", "--sensor", d / "sensor.json",
                          "--quiet", "--mcap", named])
    # Killed once the first chunk is on disk (a debug build takes a while to start).
    deadline = time.time() + 180
    while time.time() < deadline and (not bag.exists() or bag.stat().st_size == 0):
        time.sleep(0.2)
    time.sleep(1.5)
    p.kill()
    p.wait()
    channels, messages = {}, 0
    try:
        for rec in StreamReader(open(bag, "rb")).records:
            if isinstance(rec, Channel):
                channels[rec.id] = rec.topic
            if isinstance(rec, Message):
                assert rec.channel_id in channels
                messages += 1
    except Exception:  # the unfinished last chunk
        pass
    assert messages > 0
    assert "/visuotact/contact/active" in channels.values()
    assert not named.exists()


def test_record_writes_the_bag_that_export_writes(session):
    """`record --mcap` writes the bag as the session is recorded; `export mcap` of the finished
    session must give the same messages (raw CDR, stamps to the nanosecond; frames as PNG on
    both), and the force messages must equal force.csv to 1e-9 N."""
    import json

    d, _ = session
    s, live, later = d / "recorded", d / "recorded.mcap", d / "exported.mcap"
    # 2 fps: a debug build keeps up (the simulated camera drops frames it cannot make in time).
    cli("record", "-o", s, "--source", "sim:cone", "--press-s", "4", "--rest-s", "0.2", "--fps", "2",
        "--references", "0", "--force", "udp:127.0.0.1:0", "--force-rate-hz", "500",
        "--sensor", d / "sensor.json", "--save-frames", "--mcap", live, "--mcap-images",
        "--namespace", "/cone")
    cli("export", "mcap", s, "-o", later, "--namespace", "/cone", "--sensor", d / "sensor.json")

    from mcap.reader import make_reader

    def by_topic(path):
        """topic → [(log time, raw CDR)]."""
        out = {}
        with open(path, "rb") as f:
            for _, channel, message in make_reader(f).iter_messages():
                out.setdefault(channel.topic, []).append((message.log_time, message.data))
        return out

    a, b = by_topic(live), by_topic(later)
    assert set(a) == set(b) == {"/cone/ft_sensor/wrench", "/cone/markers",
                                "/cone/image/compressed", "/diagnostics"}
    frames = rows(s / "frames.csv")
    assert len(a["/cone/markers"]) == len(frames) >= 3
    for topic in a:
        assert len(a[topic]) == len(b[topic]), topic
        for (tx, x), (ty, y) in zip(a[topic], b[topic]):
            assert tx == ty, topic
            if topic != "/cone/image/compressed":
                assert x == y, topic
    decoded = {}
    for m in read_ros2_messages(str(live)):
        decoded.setdefault(m.channel.topic, []).append(m.ros_msg)
    start = json.loads((s / "session.json").read_text())["started_unix_s"]
    assert start > 1.7e9
    force = rows(s / "force.csv")
    assert len(decoded["/cone/ft_sensor/wrench"]) == len(force) > 100
    # The sender's clock onto the recording's: plus the least delay (recv_s − timestamp_s) seen
    # up to each sample. The simulated sender starts its own clock in its own thread, so that
    # delay can be a fraction of a millisecond below zero (a real F/T box's can be anything).
    least = float("inf")
    for r, m in zip(force, decoded["/cone/ft_sensor/wrench"]):
        w = m.wrench
        got = [w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z]
        assert all(abs(g - float(r[k])) <= 1e-9 for g, k in zip(got, AXES)), (got, r)
        least = min(least, float(r["recv_s"]) - float(r["timestamp_s"]))
        assert abs(least) < 0.1, least
        assert abs(stamp_s(m.header) - (start + float(r["timestamp_s"]) + least)) <= 1e-6
    for f, m in zip(frames, decoded["/cone/markers"]):
        assert abs(stamp_s(m.header) - (start + float(f["timestamp_s"]))) <= 1e-6

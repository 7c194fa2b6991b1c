"""`visuotact run --ros2`: the live topics over DDS, received by a subscriber written with
`cyclonedds` (the DDS behind ROS 2's `rmw_cyclonedds_cpp`) using the ROS 2 type names, on
loopback without multicast (Cyclone told of the peer 127.0.0.1, as a ROS 2 machine would be
configured for a loopback-only publisher). Every message received must equal the estimate of
the same frame in the run's JSON lines; stamps must keep one offset from the frames' times."""

import json
import math
import os
import subprocess
import time
from dataclasses import dataclass

import pytest

os.environ.setdefault(
    "CYCLONEDDS_URI",
    "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/>"
    "</Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery>"
    "<ParticipantIndex>auto</ParticipantIndex><Peers><Peer address=\"127.0.0.1\"/></Peers>"
    "</Discovery></Domain></CycloneDDS>")

from cyclonedds.core import Policy, Qos  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.idl import IdlStruct  # noqa: E402
from cyclonedds.idl.types import float64, int32, uint32  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402

BIN = os.environ.get("VISUOTACT_BIN", "visuotact")


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Wrench(IdlStruct, typename="geometry_msgs::msg::dds_::Wrench_"):
    force: Vector3
    torque: Vector3


@dataclass
class WrenchStamped(IdlStruct, typename="geometry_msgs::msg::dds_::WrenchStamped_"):
    header: Header
    wrench: Wrench


@dataclass
class PointStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PointStamped_"):
    header: Header
    point: Point


def cli(*args):
    subprocess.run([BIN, *map(str, args)], check=True, capture_output=True)


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    """Small models: the cone's force (fx, fy, fz) and the touch sensor's contact (x, y,
    depth); accuracy does not matter here, only that estimates flow."""
    d = tmp_path_factory.mktemp("dds")
    cli("simulate", "--sensor", "cone", "--protocol", "press", "--duration-s", "3",
        "--references", "2", "--force-rate-hz", "100", "-o", d / "cone")
    cli("calibrate", d / "cone/reference", "-o", d / "cone.json")
    cli("extract", "--sensor", d / "cone.json", d / "cone/frames", "-o", d / "cone.csv")
    cli("train", "--features", d / "cone.csv", "--labels", d / "cone/labels.csv", "--targets",
        "fx_n,fy_n,fz_n", "--hidden", "4", "--ensemble", "1", "--drop-incomplete",
        "--sensor", d / "cone.json", "-o", d / "cone_model.json")
    cli("simulate", "--sensor", "iats", "--protocol", "random", "--touches", "20",
        "--references", "2", "-o", d / "iats")
    cli("calibrate", d / "iats/reference", "-o", d / "iats.json")
    cli("extract", "--sensor", d / "iats.json", d / "iats/frames", "-o", d / "iats.csv")
    cli("train", "--features", d / "iats.csv", "--labels", d / "iats/labels.csv", "--targets",
        "x_mm,y_mm,depth_mm", "--hidden", "4", "--ensemble", "1", "--drop-incomplete",
        "--sensor", d / "iats.json", "-o", d / "iats_model.json")
    return d


def receive(topic, kind, args):
    """Starts the reader, then `visuotact run --ros2 ARGS`; returns the samples received and
    the run's JSON lines."""
    dp = DomainParticipant(0)
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)),
              Policy.Durability.Volatile, Policy.History.KeepLast(100))
    reader = DataReader(dp, Topic(dp, topic, kind, qos=qos), qos=qos)
    p = subprocess.Popen([BIN, "run", "--ros2", *map(str, args)], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    got = []

    def take():
        # The writer's end arrives as an InvalidSample (instance state), not data.
        got.extend(x for x in reader.take(N=100) if isinstance(x, kind))

    deadline = time.time() + 240
    while p.poll() is None and time.time() < deadline:
        take()
        time.sleep(0.005)
    out, err = p.communicate(timeout=30)
    time.sleep(0.2)
    take()
    assert p.returncode == 0, err
    assert "published" in err
    lines = [json.loads(line) for line in out.splitlines()]
    return got, lines


def stamp_s(h):
    return h.stamp.sec + h.stamp.nanosec * 1e-9


def matched(got, lines, value_of):
    """Each sample's JSON line (by equal values); checks one stamp offset for all."""
    by_values = {}
    for line in lines:
        v = value_of(line)
        if v is not None:
            by_values.setdefault(v, line)
    offsets = []
    for s in got:
        key = tuple(s[1])
        assert key in by_values, key
        line = by_values[key]
        offsets.append(stamp_s(s[0]) - line["timestamp_s"])
    assert max(offsets) - min(offsets) < 2e-6, (min(offsets), max(offsets))
    stamps = [stamp_s(s[0]) for s in got]
    assert stamps == sorted(stamps)


def targets(line):
    return {t["name"]: t["value"] for t in line["targets"]}


def test_wrench_reaches_a_cyclonedds_subscriber(models):
    got, lines = receive("rt/visuotact/wrench", WrenchStamped,
                         ["--source", "sim:cone", "--model", models / "cone_model.json",
                          "--max-frames", "150"])
    assert len(got) >= 10, len(got)
    assert all(m.header.frame_id == "visuotact" for m in got)
    assert all(math.isnan(m.wrench.torque.x) for m in got)

    def value_of(line):
        t = targets(line)
        return (t["fx_n"], t["fy_n"], t["fz_n"]) if "fz_n" in t else None

    samples = [(m.header, (m.wrench.force.x, m.wrench.force.y, m.wrench.force.z)) for m in got]
    matched(samples, lines, value_of)


def test_contact_point_reaches_a_cyclonedds_subscriber(models):
    got, lines = receive("rt/visuotact/contact", PointStamped,
                         ["--source", "sim:iats", "--model", models / "iats_model.json",
                          "--sim-frames", "20", "--max-frames", "120"])
    assert len(got) >= 10, len(got)

    def value_of(line):
        t = targets(line)
        if "x_mm" not in t:
            return None
        return (t["x_mm"] / 1000, t["y_mm"] / 1000, -t["depth_mm"] / 1000)

    samples = [(m.header, (m.point.x, m.point.y, m.point.z)) for m in got]
    matched(samples, lines, value_of)

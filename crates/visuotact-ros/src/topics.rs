//! visuotact's ROS 2 topics and how a frame's results map onto them.
//!
//! | topic | type | content |
//! |---|---|---|
//! | `NS/wrench` | `geometry_msgs/msg/WrenchStamped` | the estimated force (N) and torque (N·m): `fx_n`…`tz_nm`; an axis the model does not estimate is NaN; published when the model estimates at least one axis |
//! | `NS/ft_sensor/wrench` | `geometry_msgs/msg/WrenchStamped` | the measured force/torque sensor (a session's `force.csv`), same axes |
//! | `NS/contact` | `geometry_msgs/msg/PointStamped` | the estimated contact in metres: x = `x_mm`/1000, y = `y_mm`/1000, z = −`depth_mm`/1000 (NaN without depth); published when x and y are estimated |
//! | `NS/contact/active` | `std_msgs/msg/Bool` | the contact rule (live runs) |
//! | `NS/slip` | `std_msgs/msg/Float64` | the slip score, the probability that the object slips (live runs with `--slip`) |
//! | `NS/slip/state` | `std_msgs/msg/String` | the slip state: `stick`, `incipient` or `slip` (live runs with `--slip`) |
//! | `NS/markers` | `sensor_msgs/msg/PointCloud2` | one point per marker: `x`, `y`, `z` (= 0) its reference position and `dx`, `dy` its displacement, image pixels, `float32`; `status` `uint8` (0 found, 1 lost); with a scaled sensor (`calibrate --pitch-mm`) also `dx_mm`, `dy_mm` (`float32`, millimetres) |
//! | `NS/image/compressed` | `sensor_msgs/msg/CompressedImage` | the frame, PNG |
//! | `/diagnostics` | `diagnostic_msgs/msg/DiagnosticArray` | marker health: one status named `NS: markers`, level OK, WARN (markers lost or filled, reference under contact) or ERROR (none found) |
//!
//! `NS` is [`OutputConfig::namespace`] (`/visuotact`; one per sensor when several run side by
//! side). Frames: the wrench and contact are in the sensor frame [`OutputConfig::frame_id`]
//! (origin and x, y axes as the sensor's labels define them — for seed 000's membrane its
//! centre, x and y in the skin plane — z out of the skin), the marker cloud and image in
//! `FRAME_ID/image` (x right, y down, pixels). Stamps: each frame's timestamp.

use visuotact_pipeline::live::{Health, TargetEstimate};
use visuotact_pipeline::output::{
    FrameParts, FrameTarget, MarkerPoint, OutputConfig, OutputError, WRENCH_TARGETS,
};

use crate::bag::Bag;
use crate::msg::{
    level, Bool, CompressedImage, DiagnosticArray, DiagnosticStatus, Float64, Header, PointCloud2,
    PointField, PointStamped, RosMessage, StringMsg, WrenchStamped, FLOAT32, UINT8,
};
use crate::RosError;

/// The wrench among `targets` (NaN for axes not estimated); `None` when none is.
pub fn wrench_from_targets(targets: &[TargetEstimate]) -> Option<[f64; 6]> {
    let mut w = [f64::NAN; 6];
    let mut any = false;
    for (slot, name) in w.iter_mut().zip(WRENCH_TARGETS) {
        if let Some(t) = targets.iter().find(|t| t.name == name) {
            *slot = t.value;
            any = true;
        }
    }
    any.then_some(w)
}

/// The contact point in metres (z = −depth), when `x_mm` and `y_mm` are estimated.
pub fn contact_from_targets(targets: &[TargetEstimate]) -> Option<[f64; 3]> {
    let get = |n: &str| targets.iter().find(|t| t.name == n).map(|t| t.value);
    let (x, y) = (get("x_mm")?, get("y_mm")?);
    let z = get("depth_mm").map_or(f64::NAN, |d| -d);
    Some([x / 1000.0, y / 1000.0, z / 1000.0])
}

/// The marker cloud's point layout: x, y, z, dx, dy as `float32`, status as `uint8`; with a
/// scale, dx_mm and dy_mm as `float32` after the status's padding.
fn cloud_fields(scaled: bool) -> Vec<PointField> {
    let f = |name: &str, offset, datatype| PointField {
        name: name.into(),
        offset,
        datatype,
        count: 1,
    };
    let mut fields = vec![
        f("x", 0, FLOAT32),
        f("y", 4, FLOAT32),
        f("z", 8, FLOAT32),
        f("dx", 12, FLOAT32),
        f("dy", 16, FLOAT32),
        f("status", 20, UINT8),
    ];
    if scaled {
        fields.push(f("dx_mm", CLOUD_POINT_STEP, FLOAT32));
        fields.push(f("dy_mm", CLOUD_POINT_STEP + 4, FLOAT32));
    }
    fields
}

/// Bytes per marker point (without a scale; with one, 8 more for dx_mm and dy_mm).
pub const CLOUD_POINT_STEP: u32 = 24;

/// The marker cloud message; with the sensor's scale (`mm_per_px`), each point also carries
/// its displacement in millimetres.
pub fn marker_cloud(
    header: Header,
    markers: &[MarkerPoint],
    mm_per_px: Option<f64>,
) -> PointCloud2 {
    let point_step = CLOUD_POINT_STEP + if mm_per_px.is_some() { 8 } else { 0 };
    let mut data = Vec::with_capacity(markers.len() * point_step as usize);
    for m in markers {
        for v in [m.x_px, m.y_px, 0.0, m.dx_px, m.dy_px] {
            data.extend_from_slice(&v.to_le_bytes());
        }
        data.extend_from_slice(&[u8::from(!m.found), 0, 0, 0]);
        if let Some(s) = mm_per_px {
            for v in [m.dx_px, m.dy_px] {
                data.extend_from_slice(&((f64::from(v) * s) as f32).to_le_bytes());
            }
        }
    }
    PointCloud2 {
        header,
        width: u32::try_from(markers.len()).unwrap_or(u32::MAX),
        fields: cloud_fields(mm_per_px.is_some()),
        point_step,
        data,
        is_dense: markers.iter().all(|m| m.found),
    }
}

/// The marker health as one diagnostic status.
pub fn health_status(
    cfg: &OutputConfig,
    h: &Health,
    mut values: Vec<(String, String)>,
) -> DiagnosticStatus {
    let (lvl, message) = if h.ok == 0 {
        (level::ERROR, "no marker found".to_string())
    } else if h.reference_under_contact {
        (level::WARN, "reference taken under contact".to_string())
    } else if h.lost > 0 || h.filled > 0 {
        (level::WARN, format!("{} markers lost", h.lost))
    } else {
        (level::OK, "all markers found".to_string())
    };
    for (k, v) in [
        ("ok", h.ok),
        ("lost", h.lost),
        ("merged", h.merged),
        ("ambiguous", h.ambiguous),
        ("split", h.split),
        ("filled", h.filled),
        ("drifting", h.drifting),
    ] {
        values.push((k.to_string(), v.to_string()));
    }
    DiagnosticStatus {
        level: lvl,
        name: format!("{}: markers", cfg.namespace),
        message,
        hardware_id: cfg.frame_id.clone(),
        values,
    }
}

/// The entry made for `topic` in a table of per-topic writers or channels, checked to carry
/// type `name`: one topic, one type. (Used by the live publishers only.)
#[cfg(any(feature = "dds", feature = "foxglove"))]
pub(crate) fn typed_entry<'a, T>(
    table: &'a std::collections::HashMap<String, (&'static str, T)>,
    topic: &str,
    name: &'static str,
) -> Result<&'a T, RosError> {
    match table.get(topic) {
        Some((was, t)) if *was == name => Ok(t),
        Some((was, _)) => Err(RosError::TopicType {
            topic: topic.to_string(),
            was,
            now: name,
        }),
        None => Err(RosError::Config(format!(
            "topic {topic}: nothing made for it"
        ))),
    }
}

/// Where messages go: a bag ([`Bag`]) or live DDS writers ([`crate::dds::DdsPublisher`]).
pub trait Publish {
    /// Publishes `msg` on `topic`, stamped `stamp_ns` (nanoseconds since the UNIX epoch).
    fn publish<M: RosMessage>(
        &mut self,
        topic: &str,
        stamp_ns: u64,
        msg: &M,
    ) -> Result<(), RosError>;
}

impl Publish for Bag {
    fn publish<M: RosMessage>(
        &mut self,
        topic: &str,
        stamp_ns: u64,
        msg: &M,
    ) -> Result<(), RosError> {
        self.write(topic, stamp_ns, msg)
    }
}

/// A target that can make a topic's channel before its first message (a live server, so that
/// a client connecting before the first frame is told of every topic at once).
pub trait Declare {
    /// Makes `topic`'s channel for messages of type `M` (nothing if it exists).
    fn declare<M: RosMessage>(&mut self, topic: &str) -> Result<(), RosError>;
}

/// Declares every topic [`write_frame`] may publish under `cfg`: wrench, measured wrench,
/// contact, contact rule, marker cloud, the frames when `cfg.images`, and `/diagnostics`.
pub fn declare_frame_topics<D: Declare>(d: &mut D, cfg: &OutputConfig) -> Result<(), RosError> {
    d.declare::<WrenchStamped>(&cfg.topic("wrench"))?;
    d.declare::<WrenchStamped>(&cfg.topic("ft_sensor/wrench"))?;
    d.declare::<PointStamped>(&cfg.topic("contact"))?;
    d.declare::<Bool>(&cfg.topic("contact/active"))?;
    d.declare::<Float64>(&cfg.topic("slip"))?;
    d.declare::<StringMsg>(&cfg.topic("slip/state"))?;
    d.declare::<PointCloud2>(&cfg.topic("markers"))?;
    if cfg.images {
        d.declare::<CompressedImage>(&cfg.topic("image/compressed"))?;
    }
    d.declare::<DiagnosticArray>("/diagnostics")
}

/// Declares the topics of one sensor under `cfg` (`sensors` empty) or of each sensor of a run
/// of several under [`OutputConfig::for_sensor`].
pub fn declare_sensor_topics<D: Declare>(
    d: &mut D,
    cfg: &OutputConfig,
    sensors: &[String],
) -> Result<(), RosError> {
    if sensors.is_empty() {
        return declare_frame_topics(d, cfg);
    }
    for name in sensors {
        declare_frame_topics(d, &cfg.for_sensor(name))?;
    }
    Ok(())
}

impl FrameTarget for Bag {
    fn write_frame(&mut self, cfg: &OutputConfig, f: FrameParts<'_>) -> Result<(), OutputError> {
        write_frame(self, cfg, f).map_err(OutputError::target)
    }
}

/// Publishes one frame's messages to `bag` (or any [`Publish`]).
pub fn write_frame<P: Publish>(
    bag: &mut P,
    cfg: &OutputConfig,
    f: FrameParts<'_>,
) -> Result<(), RosError> {
    let at = f.stamp_ns;
    let header = || Header::at_ns(at, &cfg.frame_id);
    let image_frame = format!("{}/image", cfg.frame_id);
    let wrench = |w: [f64; 6]| WrenchStamped {
        header: header(),
        force: [w[0], w[1], w[2]],
        torque: [w[3], w[4], w[5]],
    };
    if let Some(w) = wrench_from_targets(f.targets) {
        bag.publish(&cfg.topic("wrench"), at, &wrench(w))?;
    }
    if let Some(w) = f.measured {
        bag.publish(&cfg.topic("ft_sensor/wrench"), at, &wrench(w))?;
    }
    if let Some(point) = contact_from_targets(f.targets) {
        let m = PointStamped {
            header: header(),
            point,
        };
        bag.publish(&cfg.topic("contact"), at, &m)?;
    }
    if let Some(c) = f.contact {
        bag.publish(&cfg.topic("contact/active"), at, &Bool(c))?;
    }
    if let Some(s) = f.slip {
        bag.publish(&cfg.topic("slip"), at, &Float64(s.score))?;
        bag.publish(
            &cfg.topic("slip/state"),
            at,
            &StringMsg(s.state.name().into()),
        )?;
    }
    if let Some(markers) = f.markers {
        let m = marker_cloud(Header::at_ns(at, &image_frame), markers, f.mm_per_px);
        bag.publish(&cfg.topic("markers"), at, &m)?;
    }
    if let Some(png) = f.png {
        let m = CompressedImage {
            header: Header::at_ns(at, &image_frame),
            format: "png".into(),
            data: png,
        };
        bag.publish(&cfg.topic("image/compressed"), at, &m)?;
    }
    if let Some((h, values)) = f.health {
        let m = DiagnosticArray {
            header: header(),
            status: vec![health_status(cfg, h, values)],
        };
        bag.publish("/diagnostics", at, &m)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use visuotact_pipeline::slip::SlipEstimate;

    fn f32_at(data: &[u8], at: usize) -> f32 {
        f32::from_le_bytes(data[at..at + 4].try_into().unwrap())
    }

    /// Records (topic, message type) of what is declared or published.
    #[derive(Default)]
    struct Seen(std::collections::BTreeSet<(String, &'static str)>);

    impl Declare for Seen {
        fn declare<M: RosMessage>(&mut self, topic: &str) -> Result<(), RosError> {
            self.0.insert((topic.to_string(), M::NAME));
            Ok(())
        }
    }

    impl Publish for Seen {
        fn publish<M: RosMessage>(&mut self, topic: &str, _: u64, _: &M) -> Result<(), RosError> {
            self.0.insert((topic.to_string(), M::NAME));
            Ok(())
        }
    }

    /// A live server makes its channels before the first frame: what it declares is exactly
    /// what a frame with every part publishes, topic and type, with and without the images.
    #[test]
    fn the_declared_topics_are_those_a_full_frame_publishes() {
        let targets: Vec<TargetEstimate> = ["x_mm", "y_mm", "depth_mm"]
            .iter()
            .chain(&WRENCH_TARGETS)
            .map(|n| TargetEstimate {
                name: (*n).to_string(),
                value: 1.0,
                std: None,
            })
            .collect();
        let markers = [MarkerPoint {
            x_px: 1.0,
            y_px: 2.0,
            dx_px: 0.0,
            dy_px: 0.0,
            found: true,
        }];
        let health = Health::default();
        for images in [true, false] {
            let cfg = OutputConfig {
                images,
                ..OutputConfig::default()
            }
            .for_sensor("left");
            let frame = FrameParts {
                targets: &targets,
                contact: Some(true),
                measured: Some([0.0; 6]),
                markers: Some(&markers),
                png: images.then(Vec::new),
                health: Some((&health, Vec::new())),
                slip: Some(SlipEstimate {
                    state: visuotact_pipeline::slip::SlipState::Slip,
                    score: 0.7,
                    field: Default::default(),
                }),
                ..FrameParts::default()
            };
            let (mut published, mut declared) = (Seen::default(), Seen::default());
            write_frame(&mut published, &cfg, frame).unwrap();
            declare_frame_topics(&mut declared, &cfg).unwrap();
            assert_eq!(declared.0, published.0);
            assert_eq!(declared.0.len(), 8 + usize::from(images));
            assert!(declared
                .0
                .contains(&("/visuotact/left/slip/state".into(), StringMsg::NAME)));
            assert!(declared
                .0
                .contains(&("/visuotact/left/contact/active".into(), Bool::NAME)));
        }
    }

    /// Without a scale the cloud keeps its pixel layout; with one, each point gains dx_mm and
    /// dy_mm (pixels × mm per pixel) after the status, and a lost marker's stay NaN.
    #[test]
    fn a_scaled_sensor_gives_the_marker_cloud_millimetres() {
        let markers = [
            MarkerPoint {
                x_px: 10.0,
                y_px: 20.0,
                dx_px: 2.5,
                dy_px: -4.0,
                found: true,
            },
            MarkerPoint {
                x_px: 30.0,
                y_px: 40.0,
                dx_px: f32::NAN,
                dy_px: f32::NAN,
                found: false,
            },
        ];
        let plain = marker_cloud(Header::at_ns(0, "f"), &markers, None);
        let names: Vec<&str> = plain.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["x", "y", "z", "dx", "dy", "status"]);
        assert_eq!((plain.point_step, plain.data.len()), (24, 48));
        let scaled = marker_cloud(Header::at_ns(0, "f"), &markers, Some(0.1));
        let names: Vec<(&str, u32)> = scaled
            .fields
            .iter()
            .map(|f| (f.name.as_str(), f.offset))
            .collect();
        assert_eq!(
            names,
            [
                ("x", 0),
                ("y", 4),
                ("z", 8),
                ("dx", 12),
                ("dy", 16),
                ("status", 20),
                ("dx_mm", 24),
                ("dy_mm", 28)
            ]
        );
        assert_eq!((scaled.point_step, scaled.data.len()), (32, 64));
        let d = &scaled.data;
        assert_eq!((f32_at(d, 12), f32_at(d, 16)), (2.5, -4.0));
        assert_eq!((f32_at(d, 24), f32_at(d, 28)), (0.25, -0.4));
        assert_eq!((d[20], d[52]), (0, 1));
        assert!(f32_at(d, 32 + 24).is_nan() && f32_at(d, 32 + 28).is_nan());
        // The pixel part of each point is the same bytes as without the scale.
        assert_eq!(&d[..24], &plain.data[..24]);
        assert_eq!(&d[32..56], &plain.data[24..48]);
    }
}

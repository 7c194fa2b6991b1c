//! The standard ROS 2 messages visuotact publishes, with their CDR encoding and their full
//! `.msg` definitions (what an MCAP `ros2msg` schema holds: the message, then each message it
//! uses after a line of 80 `=` and `MSG: package/Type`). Field for field as in `common_interfaces`
//! (`std_msgs`, `geometry_msgs`, `sensor_msgs`, `diagnostic_msgs`) and `builtin_interfaces`.

use crate::cdr::CdrWriter;

/// A ROS 2 message type visuotact writes.
pub trait RosMessage {
    /// The type's full name (`geometry_msgs/msg/WrenchStamped`).
    const NAME: &'static str;
    /// The `ros2msg` schema: the definition with those of the types it uses.
    const DEFINITION: &'static str;
    /// Appends the message's fields to `w`.
    fn encode(&self, w: &mut CdrWriter);
    /// The message as one CDR buffer.
    fn to_cdr(&self) -> Vec<u8> {
        self.to_cdr_in(Vec::new())
    }
    /// The message as one CDR buffer, written into `buf` (cleared first, its capacity kept).
    fn to_cdr_in(&self, buf: Vec<u8>) -> Vec<u8> {
        let mut w = CdrWriter::reuse(buf);
        self.encode(&mut w);
        w.into_bytes()
    }
}

macro_rules! sep {
    ($name:literal) => {
        concat!(
            "================================================================================\nMSG: ",
            $name,
            "\n"
        )
    };
}

/// The definitions of `std_msgs/Header` and the `builtin_interfaces/Time` it uses, as every
/// stamped message's schema carries them.
macro_rules! header_deps {
    () => {
        concat!(
            sep!("std_msgs/Header"),
            "builtin_interfaces/Time stamp\nstring frame_id\n",
            sep!("builtin_interfaces/Time"),
            "int32 sec\nuint32 nanosec\n"
        )
    };
}

const HEADER_DEF: &str = header_deps!();

/// `std_msgs/Header`: a stamp (`builtin_interfaces/Time`) and a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Seconds since the UNIX epoch (`stamp.sec`).
    pub sec: i32,
    /// The rest, nanoseconds (`stamp.nanosec`).
    pub nanosec: u32,
    /// The coordinate frame the data is in.
    pub frame_id: String,
}

impl Header {
    /// A header at `ns` nanoseconds since the UNIX epoch.
    pub fn at_ns(ns: u64, frame_id: &str) -> Self {
        Self {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
            frame_id: frame_id.to_string(),
        }
    }

    fn encode(&self, w: &mut CdrWriter) {
        w.i32(self.sec);
        w.u32(self.nanosec);
        w.string(&self.frame_id);
    }
}

/// `geometry_msgs/WrenchStamped`: force (N) and torque (N·m).
#[derive(Clone, Debug, PartialEq)]
pub struct WrenchStamped {
    /// Stamp and frame.
    pub header: Header,
    /// Force, N.
    pub force: [f64; 3],
    /// Torque, N·m.
    pub torque: [f64; 3],
}

impl RosMessage for WrenchStamped {
    const NAME: &'static str = "geometry_msgs/msg/WrenchStamped";
    const DEFINITION: &'static str = concat!(
        "std_msgs/Header header\nWrench wrench\n",
        header_deps!(),
        sep!("geometry_msgs/Wrench"),
        "Vector3 force\nVector3 torque\n",
        sep!("geometry_msgs/Vector3"),
        "float64 x\nfloat64 y\nfloat64 z\n"
    );
    fn encode(&self, w: &mut CdrWriter) {
        self.header.encode(w);
        for v in self.force.iter().chain(&self.torque) {
            w.f64(*v);
        }
    }
}

/// `geometry_msgs/PointStamped`: a point, metres.
#[derive(Clone, Debug, PartialEq)]
pub struct PointStamped {
    /// Stamp and frame.
    pub header: Header,
    /// x, y, z in metres.
    pub point: [f64; 3],
}

impl RosMessage for PointStamped {
    const NAME: &'static str = "geometry_msgs/msg/PointStamped";
    const DEFINITION: &'static str = concat!(
        "std_msgs/Header header\nPoint point\n",
        header_deps!(),
        sep!("geometry_msgs/Point"),
        "float64 x\nfloat64 y\nfloat64 z\n"
    );
    fn encode(&self, w: &mut CdrWriter) {
        self.header.encode(w);
        for v in self.point {
            w.f64(v);
        }
    }
}

/// `std_msgs/Bool`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bool(pub bool);

impl RosMessage for Bool {
    const NAME: &'static str = "std_msgs/msg/Bool";
    const DEFINITION: &'static str = "bool data\n";
    fn encode(&self, w: &mut CdrWriter) {
        w.bool(self.0);
    }
}

/// `std_msgs/Float64`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Float64(pub f64);

impl RosMessage for Float64 {
    const NAME: &'static str = "std_msgs/msg/Float64";
    const DEFINITION: &'static str = "float64 data\n";
    fn encode(&self, w: &mut CdrWriter) {
        w.f64(self.0);
    }
}

/// `std_msgs/String`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StringMsg(pub String);

impl RosMessage for StringMsg {
    const NAME: &'static str = "std_msgs/msg/String";
    const DEFINITION: &'static str = "string data\n";
    fn encode(&self, w: &mut CdrWriter) {
        w.string(&self.0);
    }
}

/// One field of a point cloud (`sensor_msgs/PointField`).
#[derive(Clone, Debug, PartialEq)]
pub struct PointField {
    /// Field name.
    pub name: String,
    /// Byte offset in a point.
    pub offset: u32,
    /// `PointField` datatype constant (7 = FLOAT32, 2 = UINT8).
    pub datatype: u8,
    /// Elements per point.
    pub count: u32,
}

/// `PointField::FLOAT32`.
pub const FLOAT32: u8 = 7;
/// `PointField::UINT8`.
pub const UINT8: u8 = 2;

/// `sensor_msgs/PointCloud2`, unorganised (height 1), little-endian.
#[derive(Clone, Debug, PartialEq)]
pub struct PointCloud2 {
    /// Stamp and frame.
    pub header: Header,
    /// Points.
    pub width: u32,
    /// The fields of one point.
    pub fields: Vec<PointField>,
    /// Bytes per point.
    pub point_step: u32,
    /// The points, `width · point_step` bytes.
    pub data: Vec<u8>,
    /// No invalid (NaN) point.
    pub is_dense: bool,
}

impl RosMessage for PointCloud2 {
    const NAME: &'static str = "sensor_msgs/msg/PointCloud2";
    const DEFINITION: &'static str = concat!(
        "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\n",
        "bool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n",
        header_deps!(),
        sep!("sensor_msgs/PointField"),
        "uint8 INT8 = 1\nuint8 UINT8 = 2\nuint8 INT16 = 3\nuint8 UINT16 = 4\nuint8 INT32 = 5\n",
        "uint8 UINT32 = 6\nuint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\n",
        "string name\nuint32 offset\nuint8 datatype\nuint32 count\n"
    );
    fn encode(&self, w: &mut CdrWriter) {
        self.header.encode(w);
        w.u32(1);
        w.u32(self.width);
        w.seq_len(self.fields.len());
        for f in &self.fields {
            w.string(&f.name);
            w.u32(f.offset);
            w.u8(f.datatype);
            w.u32(f.count);
        }
        w.bool(false);
        w.u32(self.point_step);
        w.u32(self.point_step.saturating_mul(self.width));
        w.bytes_seq(&self.data);
        w.bool(self.is_dense);
    }
}

/// `sensor_msgs/CompressedImage`.
#[derive(Clone, Debug, PartialEq)]
pub struct CompressedImage {
    /// Stamp and frame.
    pub header: Header,
    /// `png` or `jpeg`.
    pub format: String,
    /// The encoded image.
    pub data: Vec<u8>,
}

impl RosMessage for CompressedImage {
    const NAME: &'static str = "sensor_msgs/msg/CompressedImage";
    const DEFINITION: &'static str = concat!(
        "std_msgs/Header header\nstring format\nuint8[] data\n",
        header_deps!()
    );
    fn encode(&self, w: &mut CdrWriter) {
        self.header.encode(w);
        w.string(&self.format);
        w.bytes_seq(&self.data);
    }
}

/// `diagnostic_msgs/DiagnosticStatus` levels.
pub mod level {
    /// OK.
    pub const OK: u8 = 0;
    /// WARN.
    pub const WARN: u8 = 1;
    /// ERROR.
    pub const ERROR: u8 = 2;
}

/// `diagnostic_msgs/DiagnosticStatus`.
#[derive(Clone, Debug, PartialEq)]
pub struct DiagnosticStatus {
    /// [`level`].
    pub level: u8,
    /// What is diagnosed (`visuotact: markers`).
    pub name: String,
    /// One line for a person.
    pub message: String,
    /// The device.
    pub hardware_id: String,
    /// Figures, as text.
    pub values: Vec<(String, String)>,
}

/// `diagnostic_msgs/DiagnosticArray`.
#[derive(Clone, Debug, PartialEq)]
pub struct DiagnosticArray {
    /// Stamp and frame.
    pub header: Header,
    /// One status per diagnosed thing.
    pub status: Vec<DiagnosticStatus>,
}

impl RosMessage for DiagnosticArray {
    const NAME: &'static str = "diagnostic_msgs/msg/DiagnosticArray";
    const DEFINITION: &'static str = concat!(
        "std_msgs/Header header\nDiagnosticStatus[] status\n",
        header_deps!(),
        sep!("diagnostic_msgs/DiagnosticStatus"),
        "byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\n",
        "string message\nstring hardware_id\nKeyValue[] values\n",
        sep!("diagnostic_msgs/KeyValue"),
        "string key\nstring value\n"
    );
    fn encode(&self, w: &mut CdrWriter) {
        self.header.encode(w);
        w.seq_len(self.status.len());
        for s in &self.status {
            w.u8(s.level);
            w.string(&s.name);
            w.string(&s.message);
            w.string(&s.hardware_id);
            w.seq_len(s.values.len());
            for (k, v) in &s.values {
                w.string(k);
                w.string(v);
            }
        }
    }
}

/// The header's definition on its own (for documentation and tests).
pub const HEADER_DEFINITION: &str = HEADER_DEF;

#[cfg(test)]
mod tests {
    use super::*;

    /// A `WrenchStamped` is the header (8 + string) then six 8-aligned doubles.
    #[test]
    fn wrench_layout() {
        let m = WrenchStamped {
            header: Header::at_ns(1_500_000_000, "s"),
            force: [1.0, 2.0, 3.0],
            torque: [4.0, 5.0, 6.0],
        };
        let b = m.to_cdr();
        // 4 header + sec 4 + nanosec 4 + len 4 + "s\0" 2 = 18 → pad to 20 (8-aligned from 4).
        assert_eq!(&b[4..8], &1i32.to_le_bytes());
        assert_eq!(&b[8..12], &500_000_000u32.to_le_bytes());
        assert_eq!(&b[12..16], &2u32.to_le_bytes());
        assert_eq!(&b[16..18], b"s\0");
        assert_eq!(b.len(), 20 + 48);
        assert_eq!(&b[20..28], &1.0f64.to_le_bytes());
        assert_eq!(&b[60..68], &6.0f64.to_le_bytes());
    }

    #[test]
    fn definitions_name_every_type_they_use() {
        for def in [
            WrenchStamped::DEFINITION,
            PointStamped::DEFINITION,
            PointCloud2::DEFINITION,
            CompressedImage::DEFINITION,
            DiagnosticArray::DEFINITION,
        ] {
            assert!(def.contains("MSG: std_msgs/Header\n"), "{def}");
            assert!(def.contains("MSG: builtin_interfaces/Time\n"), "{def}");
            assert!(HEADER_DEFINITION.lines().all(|l| def.contains(l)));
        }
    }
}

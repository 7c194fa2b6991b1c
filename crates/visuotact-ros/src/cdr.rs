//! The CDR encoding ROS 2 puts on the wire and in bags (OMG XCDR1, little-endian, as
//! `rmw_fastrtps` and `rmw_cyclonedds` write it): a 4-byte encapsulation header `00 01 00 00`,
//! then each field aligned to its own size counted from the end of that header; strings as a
//! `u32` length that counts a terminating NUL, the bytes and the NUL; sequences as a `u32`
//! count and the elements.
//!
//! ```
//! use visuotact_ros::cdr::CdrWriter;
//! let mut w = CdrWriter::new();
//! w.u8(1);
//! w.f64(0.5); // aligned to 8 after the header
//! assert_eq!(w.bytes().len(), 4 + 8 + 8);
//! ```

/// Builds one CDR message.
#[derive(Clone, Debug)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

/// Little-endian CDR (`CDR_LE`).
const ENCAPSULATION: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    /// An empty message (the encapsulation header only).
    pub fn new() -> Self {
        Self::reuse(Vec::new())
    }

    /// An empty message in `buf` (cleared; its capacity kept).
    pub fn reuse(mut buf: Vec<u8>) -> Self {
        buf.clear();
        buf.extend_from_slice(&ENCAPSULATION);
        Self { buf }
    }

    /// The message so far.
    pub fn bytes(&self) -> &[u8] {
        &self.buf
    }

    /// The message, its buffer handed over.
    pub fn into_bytes(self) -> Vec<u8> {
        self.buf
    }

    fn align(&mut self, n: usize) {
        let at = self.buf.len() - ENCAPSULATION.len();
        let pad = (n - at % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// A `uint8`, `byte` or `char`.
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }

    /// A `bool`.
    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }

    /// A `uint32`.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }

    /// A sequence's length (or a string's, with its NUL): saturates at `u32::MAX`, which no
    /// message of ours comes near (a frame would be 4 GiB).
    pub fn seq_len(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }

    /// A `string`.
    pub fn string(&mut self, s: &str) {
        self.seq_len(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }

    /// A `uint8[]`.
    pub fn bytes_seq(&mut self, b: &[u8]) {
        self.seq_len(b.len());
        self.buf.extend_from_slice(b);
    }
}

#[cfg(test)]
mod tests {
    use super::CdrWriter;

    /// `std_msgs/String "hi"` followed by a `float64`, byte for byte as ROS 2 writes it.
    #[test]
    fn strings_and_alignment_match_ros2() {
        let mut w = CdrWriter::new();
        w.string("hi");
        w.f64(1.0);
        let mut want = vec![0, 1, 0, 0, 3, 0, 0, 0, b'h', b'i', 0];
        // 7 bytes of payload so far: one pad byte to 8 (alignment counts from the payload).
        want.push(0);
        want.extend_from_slice(&1.0f64.to_le_bytes());
        assert_eq!(w.bytes(), &want[..]);
    }

    #[test]
    fn u32_after_a_byte_is_aligned_to_four() {
        let mut w = CdrWriter::new();
        w.bool(true);
        w.u32(7);
        assert_eq!(w.bytes(), &[0, 1, 0, 0, 1, 0, 0, 0, 7, 0, 0, 0]);
    }
}

//! Force/torque samples on the wire: packed little-endian `f64` values in a configurable field
//! order, as Simulink's Pack + UDP Send writes them. Both the simulated JR3 sender and the
//! receiver use this one definition.
//!
//! ```
//! use visuotact_io::force::{ForceLayout, ForceSample};
//! let layout = ForceLayout::default();
//! let s = ForceSample { timestamp_s: 1.5, values: [1.0, 2.0, 3.0, 0.1, 0.2, 0.3] };
//! let bytes = layout.encode(&s, 7);
//! assert_eq!(bytes.len(), 56);
//! assert_eq!(layout.decode(&bytes).unwrap(), s);
//! ```

use crate::table::{cell_number, TableError};

/// Why a packet layout does not parse or a packet does not decode.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PacketError {
    /// A layout names a field there is not.
    #[error("unknown force field {0:?}")]
    UnknownField(String),
    /// A layout with no field.
    #[error("the force layout is empty")]
    EmptyLayout,
    /// A layout naming a field twice.
    #[error("the force layout names {0} twice")]
    Twice(&'static str),
    /// A layout without exactly one time field.
    #[error("the force layout must name one time field (timestamp_s or counter), got {0}")]
    TimeFields(usize),
    /// A packet of another length than the layout's.
    #[error("packet of {got} bytes, expected {expected}")]
    Length {
        /// Bytes received.
        got: usize,
        /// Bytes the layout makes.
        expected: usize,
    },
    /// A field that decodes to NaN or an infinity.
    #[error("field {0} is not a finite number")]
    NotFinite(&'static str),
}

/// One field of a packet.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForceField {
    /// Seconds since the start of the stream.
    Timestamp,
    /// Sample counter (its value times the sample period gives the time).
    Counter,
    /// Force along x, N.
    Fx,
    /// Force along y, N.
    Fy,
    /// Force along z, N.
    Fz,
    /// Torque about x, N·m.
    Tx,
    /// Torque about y, N·m.
    Ty,
    /// Torque about z, N·m.
    Tz,
}

visuotact_image::names_from_str!(ForceField, "force packet field");

impl ForceField {
    /// The names [`ForceField::from_name`] and `FromStr` read (each is also what `name` writes,
    /// where the type has one).
    pub const NAMES: &'static [&'static str] = &[
        "timestamp_s",
        "counter",
        "fx_n",
        "fy_n",
        "fz_n",
        "tx_nm",
        "ty_nm",
        "tz_nm",
    ];

    /// Name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Timestamp => "timestamp_s",
            Self::Counter => "counter",
            Self::Fx => "fx_n",
            Self::Fy => "fy_n",
            Self::Fz => "fz_n",
            Self::Tx => "tx_nm",
            Self::Ty => "ty_nm",
            Self::Tz => "tz_nm",
        }
    }

    /// Parses a name written by [`ForceField::name`] (units optional: `fx` = `fx_n`).
    pub fn from_name(s: &str) -> Option<Self> {
        Some(match s {
            "timestamp_s" | "timestamp" | "t" => Self::Timestamp,
            "counter" => Self::Counter,
            "fx_n" | "fx" => Self::Fx,
            "fy_n" | "fy" => Self::Fy,
            "fz_n" | "fz" => Self::Fz,
            "tx_nm" | "tx" => Self::Tx,
            "ty_nm" | "ty" => Self::Ty,
            "tz_nm" | "tz" => Self::Tz,
            _ => return None,
        })
    }
}

/// One six-axis sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceSample {
    /// Seconds since the start of the stream.
    pub timestamp_s: f64,
    /// `[fx, fy, fz, tx, ty, tz]` in N and N·m.
    pub values: [f64; 6],
}

/// The order of fields in a packet; every field is one little-endian `f64`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ForceLayout {
    /// Fields in packet order.
    pub fields: Vec<ForceField>,
}

impl Default for ForceLayout {
    /// `timestamp_s, fx, fy, fz, tx, ty, tz` (56 bytes).
    fn default() -> Self {
        use ForceField::*;
        Self {
            fields: vec![Timestamp, Fx, Fy, Fz, Tx, Ty, Tz],
        }
    }
}

impl std::fmt::Display for ForceLayout {
    /// The field names, comma-separated (what [`ForceLayout::parse`] reads back).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names: Vec<&str> = self.fields.iter().map(|x| x.name()).collect();
        f.write_str(&names.join(","))
    }
}

visuotact_image::from_str_by_parse!(ForceLayout, PacketError);

impl ForceLayout {
    /// Parses a comma-separated field list, e.g. `counter,fx,fy,fz,tx,ty,tz`.
    pub fn parse(s: &str) -> Result<Self, PacketError> {
        let fields: Result<Vec<ForceField>, PacketError> = s
            .split(',')
            .map(|p| {
                ForceField::from_name(p.trim())
                    .ok_or_else(|| PacketError::UnknownField(p.trim().to_string()))
            })
            .collect();
        let fields = fields?;
        if fields.is_empty() {
            return Err(PacketError::EmptyLayout);
        }
        for (k, f) in fields.iter().enumerate() {
            if fields[..k].contains(f) {
                return Err(PacketError::Twice(f.name()));
            }
        }
        let times = fields
            .iter()
            .filter(|f| matches!(f, ForceField::Timestamp | ForceField::Counter))
            .count();
        if times != 1 {
            return Err(PacketError::TimeFields(times));
        }
        Ok(Self { fields })
    }

    /// Bytes per packet.
    pub fn packet_len(&self) -> usize {
        8 * self.fields.len()
    }

    /// Packs a sample; `counter` fills a `Counter` field.
    pub fn encode(&self, s: &ForceSample, counter: u64) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.packet_len());
        for f in &self.fields {
            let v = match f {
                ForceField::Timestamp => s.timestamp_s,
                ForceField::Counter => counter as f64,
                ForceField::Fx => s.values[0],
                ForceField::Fy => s.values[1],
                ForceField::Fz => s.values[2],
                ForceField::Tx => s.values[3],
                ForceField::Ty => s.values[4],
                ForceField::Tz => s.values[5],
            };
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Unpacks a packet; fields missing from the layout read as 0 (a `Counter` becomes the
    /// timestamp in samples). Fails on a wrong length or a non-finite value.
    pub fn decode(&self, bytes: &[u8]) -> Result<ForceSample, PacketError> {
        if bytes.len() != self.packet_len() {
            return Err(PacketError::Length {
                got: bytes.len(),
                expected: self.packet_len(),
            });
        }
        let mut s = ForceSample {
            timestamp_s: 0.0,
            values: [0.0; 6],
        };
        for (f, chunk) in self.fields.iter().zip(bytes.chunks_exact(8)) {
            let mut b = [0u8; 8];
            b.copy_from_slice(chunk);
            let v = f64::from_le_bytes(b);
            if !v.is_finite() {
                return Err(PacketError::NotFinite(f.name()));
            }
            match f {
                ForceField::Timestamp | ForceField::Counter => s.timestamp_s = v,
                ForceField::Fx => s.values[0] = v,
                ForceField::Fy => s.values[1] = v,
                ForceField::Fz => s.values[2] = v,
                ForceField::Tx => s.values[3] = v,
                ForceField::Ty => s.values[4] = v,
                ForceField::Tz => s.values[5] = v,
            }
        }
        Ok(s)
    }
}

/// Sends samples as UDP packets in `layout`, paced at `rate_hz` (a force sensor's stream, as
/// `simulate --udp` sends it); returns how many the receiver refused (a
/// receiver that is not listening yet refuses datagrams on loopback).
pub fn send_paced(
    sock: &std::net::UdpSocket,
    layout: &ForceLayout,
    samples: &[ForceSample],
    rate_hz: f64,
) -> usize {
    let start = std::time::Instant::now();
    let mut refused = 0usize;
    for (i, s) in samples.iter().enumerate() {
        let due = std::time::Duration::from_secs_f64(i as f64 / rate_hz);
        let now = start.elapsed();
        if due > now + std::time::Duration::from_micros(500) {
            std::thread::sleep(due - now);
        }
        if sock.send(&layout.encode(s, i as u64)).is_err() {
            refused += 1;
        }
    }
    refused
}

/// Force samples read from a CSV file: `timestamp_s` and any of `fx_n … tz_nm` (absent axes
/// read as 0), plus `recv_s` (receive time on the recorder's clock) when `record` wrote it.
#[derive(Clone, Debug, PartialEq)]
pub struct ForceTable {
    /// Sample times, seconds, in file order.
    pub timestamp_s: Vec<f64>,
    /// `[fx, fy, fz, tx, ty, tz]` per sample.
    pub values: Vec<[f64; 6]>,
    /// Which of the six axes the file has.
    pub present: [bool; 6],
    /// Receive times on the recorder's clock, when recorded over the network.
    pub recv_s: Option<Vec<f64>>,
    /// Whether an unfinished last line was left out.
    pub dropped_partial_line: bool,
}

/// Names of the six axes in files.
pub const AXES: [&str; 6] = ["fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"];

/// The least `recv_s − timestamp_s` so far (`least`, updated with the sample at `timestamp_s`
/// received at `recv_s`; non-finite pairs leave it): the sender-to-recorder clock offset as
/// known at that sample. 0 until a finite pair is seen.
pub fn to_recorder(timestamp_s: f64, recv_s: f64, least: &mut f64) -> f64 {
    let d = recv_s - timestamp_s;
    if d.is_finite() && d < *least {
        *least = d;
    }
    if least.is_finite() {
        *least
    } else {
        0.0
    }
}

impl ForceTable {
    /// How far the recorder's clock is ahead of the sender's, s: the smallest `recv_s −
    /// timestamp_s` (the least-delayed sample's), the last of [`ForceTable::recorder_times_s`]'s
    /// running offsets. 0 for a table without receive times (a force source on the recorder's
    /// own clock). A real F/T box stamps samples on its own clock (often seconds since it was
    /// powered), not the recording's.
    pub fn sender_offset_s(&self) -> f64 {
        self.running_offsets_s().last().unwrap_or(0.0)
    }

    /// The samples' times on the recorder's clock (the session's, the frames'): each
    /// `timestamp_s` plus the least `recv_s − timestamp_s` of the samples up to it in file
    /// (arrival) order ([`to_recorder`]) — what `record` itself computes as the packets
    /// arrive, so a bag written live (`record --mcap`) and one exported from the session carry
    /// the same stamps. After the first packets the offset is [`ForceTable::sender_offset_s`].
    pub fn recorder_times_s(&self) -> Vec<f64> {
        self.timestamp_s
            .iter()
            .zip(self.running_offsets_s())
            .map(|(t, offset)| t + offset)
            .collect()
    }

    /// Each sample's sender-to-recorder offset as known at it ([`to_recorder`]); all 0 without
    /// receive times.
    fn running_offsets_s(&self) -> impl Iterator<Item = f64> + '_ {
        let mut least = f64::INFINITY;
        self.timestamp_s.iter().enumerate().map(move |(k, &t)| {
            match self.recv_s.as_ref().and_then(|r| r.get(k)) {
                Some(&r) => to_recorder(t, r, &mut least),
                None => 0.0,
            }
        })
    }

    /// Puts the samples on the recorder's clock ([`ForceTable::recorder_times_s`]); the receive
    /// times stay as they are.
    pub fn onto_recorder_clock(&mut self) {
        self.timestamp_s = self.recorder_times_s();
    }

    /// Checks that the samples, on the recorder's clock ([`ForceTable::onto_recorder_clock`]
    /// first), meet the frames, which span `frames_s` (first, last) on it: their spans must
    /// overlap. An export or replay that could not put a sample beside any frame says so,
    /// naming `path`, instead of writing a force record that lies beside nothing. No samples
    /// at all meet nothing too.
    pub fn check_meets_frames(
        &self,
        path: &std::path::Path,
        (first_s, last_s): (f64, f64),
    ) -> Result<(), TableError> {
        let (lo, hi) = self
            .timestamp_s
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &t| {
                (lo.min(t), hi.max(t))
            });
        if hi >= first_s && lo <= last_s {
            return Ok(());
        }
        let span = if lo.is_finite() {
            format!("its samples span {lo:.3}–{hi:.3} s")
        } else {
            "it has no samples".to_string()
        };
        let why = if self.recv_s.is_none() && lo.is_finite() {
            " (a force sensor stamps its own clock; without a recv_s column the samples cannot \
             be put on the recording's)"
        } else {
            ""
        };
        Err(TableError::new(
            path,
            None,
            format!(
                "{span} and the frames {first_s:.3}–{last_s:.3} s: no force sample meets a \
                 frame{why}"
            ),
        ))
    }

    /// Reads a force CSV; errors name the file, line and column. A last line without a line end
    /// (a recorder stopped mid-row) is left out and reported in `dropped_partial_line`.
    pub fn read(path: &std::path::Path) -> Result<Self, TableError> {
        let text = crate::read::text_of_file(path)
            .map_err(|e| TableError::new(path, None, format!("cannot read: {e}")))?;
        Self::from_text(&text, path)
    }

    /// Reads a force CSV ([`ForceTable::read`]); an unfinished last line left out is said in
    /// `notes`, naming the file ([`crate::table::partial_line_note`]).
    pub fn read_noting(
        path: &std::path::Path,
        notes: &mut Vec<String>,
    ) -> Result<Self, TableError> {
        let t = Self::read(path)?;
        notes.extend(crate::table::partial_line_note(
            t.dropped_partial_line,
            &path.display().to_string(),
        ));
        Ok(t)
    }

    /// Parses a force CSV already in memory; `path` is the name errors give it.
    pub fn from_text(text: &str, path: &std::path::Path) -> Result<Self, TableError> {
        let fail = |line, why| TableError::new(path, line, why);
        let (text, dropped_partial_line) = crate::table::complete_lines(text);
        let mut lines = text.lines();
        let header: Vec<&str> = lines
            .next()
            .ok_or_else(|| fail(None, "empty file".to_string()))?
            .split(',')
            .map(str::trim)
            .collect();
        let col = |n: &str| header.iter().position(|h| *h == n);
        let tcol = col("timestamp_s").ok_or_else(|| {
            fail(
                None,
                format!("no `timestamp_s` column (columns: {})", header.join(", ")),
            )
        })?;
        let axes: Vec<Option<usize>> = AXES.iter().map(|a| col(a)).collect();
        if axes.iter().all(Option::is_none) {
            return Err(fail(
                None,
                format!("no force column; expected some of {}", AXES.join(", ")),
            ));
        }
        let rcol = col("recv_s");
        let mut t = Self {
            timestamp_s: Vec::new(),
            values: Vec::new(),
            present: std::array::from_fn(|i| axes[i].is_some()),
            recv_s: rcol.map(|_| Vec::new()),
            dropped_partial_line,
        };
        for (n, line) in lines.enumerate() {
            let line_no = n + 2;
            if line.trim().is_empty() {
                continue;
            }
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            if cells.len() != header.len() {
                return Err(fail(
                    Some(line_no),
                    format!(
                        "line {line_no}: {} cells, the header has {}",
                        cells.len(),
                        header.len()
                    ),
                ));
            }
            let num = |i: usize| cell_number(path, (line_no, header[i]), cells[i], false);
            let implausible = |i: usize, what: &str| {
                fail(
                    Some(line_no),
                    format!(
                        "line {line_no}, column `{}`: {} is {what}",
                        header[i], cells[i]
                    ),
                )
            };
            let ts = num(tcol)?;
            if ts.abs() > PLAUSIBLE_TIME_S {
                return Err(implausible(tcol, "not a plausible time in seconds"));
            }
            t.timestamp_s.push(ts);
            let mut v = [0.0; 6];
            for (k, a) in axes.iter().enumerate() {
                if let Some(i) = a {
                    v[k] = num(*i)?;
                    if v[k].abs() > PLAUSIBLE_LOAD {
                        return Err(implausible(*i, "beyond any plausible force or torque"));
                    }
                }
            }
            t.values.push(v);
            if let (Some(i), Some(r)) = (rcol, t.recv_s.as_mut()) {
                r.push(num(i)?);
            }
        }
        Ok(t)
    }

    /// One axis as a column (0 = fx … 5 = tz).
    pub fn axis(&self, k: usize) -> Vec<f64> {
        self.values.iter().map(|v| v[k]).collect()
    }

    /// Samples sorted by time with exact duplicate times dropped (a network may reorder and
    /// repeat packets); returns how many duplicates were dropped.
    pub fn sort_dedup(&mut self) -> usize {
        let mut idx: Vec<usize> = (0..self.timestamp_s.len()).collect();
        idx.sort_by(|&a, &b| self.timestamp_s[a].total_cmp(&self.timestamp_s[b]));
        idx.dedup_by(|a, b| self.timestamp_s[*a] == self.timestamp_s[*b]);
        let dropped = self.timestamp_s.len() - idx.len();
        self.timestamp_s = idx.iter().map(|&i| self.timestamp_s[i]).collect();
        self.values = idx.iter().map(|&i| self.values[i]).collect();
        if let Some(r) = &self.recv_s {
            self.recv_s = Some(idx.iter().map(|&i| r[i]).collect());
        }
        dropped
    }
}

/// What a [`ForceReceiver`] has seen so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReceiveStats {
    /// Datagrams received.
    pub packets: u64,
    /// Samples kept (well-formed, not repeated).
    pub kept: u64,
    /// Datagrams of the wrong size or with non-finite values, dropped.
    pub malformed: u64,
    /// Samples whose time was already received, dropped.
    pub duplicates: u64,
    /// Samples older than one already received (kept; sorted when the data set is built).
    pub reordered: u64,
    /// Samples missing from the time span covered, at the expected rate (when it is known).
    pub lost: u64,
    /// Well-formed samples that cannot be real, dropped: a time before 0 or beyond
    /// [`PLAUSIBLE_TIME_S`], more than [`LATE_S`] behind the stream or [`AHEAD_S`] ahead of it
    /// (the stream's time: the median of the last [`STREAM_WINDOW`] plausible samples' times,
    /// so no single packet — the first included — decides it), or a force or torque beyond
    /// [`PLAUSIBLE_LOAD`].
    pub rejected: u64,
}

/// The largest plausible time stamp, s (about 317 years: UNIX times pass, 1e300 does not).
pub const PLAUSIBLE_TIME_S: f64 = 1e10;
/// The largest plausible force (N) or torque (N·m) of a tactile sensor's reference.
pub const PLAUSIBLE_LOAD: f64 = 1e5;
/// How far behind the stream's time a late sample may arrive and still be kept, s.
pub const LATE_S: f64 = 1.0;
/// How far ahead of the stream's time a sample may be and still be kept, s.
pub const AHEAD_S: f64 = 60.0;
/// The stream's time is the median of this many recent plausible samples' times.
pub const STREAM_WINDOW: usize = 31;
/// The first samples are held until this many have come, so that the median can outvote a
/// wild first packet (at most [`HOLD_S`] when the sender is slow).
pub const WARMUP_SAMPLES: usize = 5;
/// Longest a sample is held during the warm-up, s.
pub const HOLD_S: f64 = 0.5;

/// Whether a sample's numbers can be real ([`ReceiveStats::rejected`], without the stream).
pub fn plausible(s: &ForceSample) -> bool {
    (0.0..=PLAUSIBLE_TIME_S).contains(&s.timestamp_s)
        && s.values.iter().all(|v| v.abs() <= PLAUSIBLE_LOAD)
}

/// Receives force samples over UDP and keeps count of what went wrong; never fails on a bad
/// packet.
pub struct ForceReceiver {
    socket: std::net::UdpSocket,
    layout: ForceLayout,
    rate_hz: Option<f64>,
    stats: ReceiveStats,
    recent: std::collections::HashSet<u64>,
    recent_order: std::collections::VecDeque<u64>,
    span: Option<(f64, f64)>,
    /// The last [`STREAM_WINDOW`] plausible samples' times.
    times: std::collections::VecDeque<f64>,
    /// Scratch for their median (no allocation per packet).
    sorted: Vec<f64>,
    /// Samples held during the warm-up, with their arrival times, and since when.
    held: Vec<(ForceSample, f64)>,
    held_since: Option<std::time::Instant>,
    /// Whether the warm-up is over.
    warm: bool,
    /// Judged samples not yet returned.
    ready: std::collections::VecDeque<Received>,
    buf: Vec<u8>,
}

/// One received sample with its arrival time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Received {
    /// The sample as sent.
    pub sample: ForceSample,
    /// Arrival time on the caller's clock, seconds.
    pub recv_s: f64,
}

impl ForceReceiver {
    /// How many recent sample times are remembered to recognise repeats.
    const MEMORY: usize = 8192;

    /// Binds `addr` (e.g. `127.0.0.1:9000`); `rate_hz` is the sender's sample rate, used to
    /// count lost samples (`None`: not counted) and, with a `Counter` field, to turn counts
    /// into seconds.
    pub fn bind(addr: &str, layout: ForceLayout, rate_hz: Option<f64>) -> std::io::Result<Self> {
        let socket = std::net::UdpSocket::bind(addr).map_err(|e| {
            std::io::Error::new(
                e.kind(),
                format!("cannot listen for force packets on {addr}: {e}"),
            )
        })?;
        Ok(Self {
            socket,
            layout,
            rate_hz,
            stats: ReceiveStats::default(),
            recent: Default::default(),
            recent_order: Default::default(),
            span: None,
            times: Default::default(),
            sorted: Vec::with_capacity(STREAM_WINDOW),
            held: Vec::new(),
            held_since: None,
            warm: false,
            ready: Default::default(),
            buf: vec![0; 65536],
        })
    }

    /// The bound address (useful after binding port 0).
    pub fn local_addr(&self) -> std::io::Result<std::net::SocketAddr> {
        self.socket.local_addr()
    }

    /// Waits up to `timeout` for the next good sample; `Ok(None)` on timeout. Bad packets are
    /// counted and skipped. `now_s` gives the arrival time on the caller's clock.
    pub fn recv(
        &mut self,
        timeout: std::time::Duration,
        now_s: impl Fn() -> f64,
    ) -> std::io::Result<Option<Received>> {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            if let Some(r) = self.ready.pop_front() {
                return Ok(Some(r));
            }
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            // A slow or short stream: held samples wait at most HOLD_S.
            let hold_left = self
                .held_since
                .map(|t| std::time::Duration::from_secs_f64(HOLD_S).saturating_sub(t.elapsed()));
            if hold_left.is_some_and(|h| h.is_zero()) {
                self.release_held();
                continue;
            }
            if left.is_zero() {
                return Ok(None);
            }
            let wait = hold_left.map_or(left, |h| h.min(left));
            self.socket.set_read_timeout(Some(wait))?;
            let n = match self.socket.recv(&mut self.buf) {
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    continue
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                // ICMP errors from an earlier send on some systems: not ours to fail on.
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionRefused => continue,
                Err(e) => return Err(e),
            };
            let recv_s = now_s();
            self.stats.packets += 1;
            let Ok(mut sample) = self.layout.decode(&self.buf[..n]) else {
                self.stats.malformed += 1;
                continue;
            };
            if self.layout.fields.contains(&ForceField::Counter) {
                if let Some(rate) = self.rate_hz {
                    sample.timestamp_s /= rate;
                }
            }
            if !plausible(&sample) {
                self.stats.rejected += 1;
                continue;
            }
            self.times.push_back(sample.timestamp_s);
            if self.times.len() > STREAM_WINDOW {
                self.times.pop_front();
            }
            if !self.warm && self.times.len() < WARMUP_SAMPLES {
                self.held.push((sample, recv_s));
                self.held_since.get_or_insert_with(std::time::Instant::now);
                continue;
            }
            self.release_held();
            self.judge(sample, recv_s);
        }
    }

    /// Ends the warm-up: the held samples are judged by the stream's time so far.
    fn release_held(&mut self) {
        self.warm = true;
        self.held_since = None;
        for (s, recv_s) in std::mem::take(&mut self.held) {
            self.judge(s, recv_s);
        }
    }

    /// Queues `s` for return when [`ForceReceiver::accept`] keeps it.
    fn judge(&mut self, s: ForceSample, recv_s: f64) {
        if let Some(sample) = self.accept(s) {
            self.ready.push_back(Received { sample, recv_s });
        }
    }

    /// The stream's time: the lower median of the recent plausible samples' times.
    fn stream_time(&mut self) -> Option<f64> {
        self.sorted.clear();
        self.sorted.extend(self.times.iter().copied());
        let k = self.sorted.len().checked_sub(1)? / 2;
        Some(*self.sorted.select_nth_unstable_by(k, f64::total_cmp).1)
    }

    /// Counts a decoded, plausible sample as kept, rejected (far from the stream's time),
    /// repeated or reordered.
    fn accept(&mut self, s: ForceSample) -> Option<ForceSample> {
        let in_stream = self
            .stream_time()
            .is_none_or(|m| s.timestamp_s >= m - LATE_S && s.timestamp_s <= m + AHEAD_S);
        if !in_stream {
            self.stats.rejected += 1;
            return None;
        }
        let key = s.timestamp_s.to_bits();
        if self.recent.contains(&key) {
            self.stats.duplicates += 1;
            return None;
        }
        self.recent.insert(key);
        self.recent_order.push_back(key);
        if self.recent_order.len() > Self::MEMORY {
            if let Some(old) = self.recent_order.pop_front() {
                self.recent.remove(&old);
            }
        }
        match &mut self.span {
            None => self.span = Some((s.timestamp_s, s.timestamp_s)),
            Some((lo, hi)) => {
                if s.timestamp_s < *hi {
                    self.stats.reordered += 1;
                }
                *lo = lo.min(s.timestamp_s);
                *hi = hi.max(s.timestamp_s);
            }
        }
        self.stats.kept += 1;
        Some(s)
    }

    /// Counts so far; `lost` is estimated from the time span and the expected rate.
    pub fn stats(&self) -> ReceiveStats {
        let mut s = self.stats;
        if let (Some(rate), Some((lo, hi))) = (self.rate_hz, self.span) {
            let expected = ((hi - lo) * rate).round() as u64 + 1;
            s.lost = expected.saturating_sub(s.kept);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sender's clock onto the recorder's: each sample shifted by the least delay seen up
    /// to it (a sample without a finite receive time leaves the offset as it is, 0 before any).
    #[test]
    fn sender_times_go_onto_the_recorder_clock_by_the_least_delay_so_far() {
        let t = ForceTable {
            timestamp_s: vec![1000.0, 1000.5, 1001.0, 1001.5],
            values: vec![[0.0; 6]; 4],
            present: [true; 6],
            recv_s: Some(vec![f64::NAN, 0.54, 1.01, 1.52]),
            dropped_partial_line: false,
        };
        let got = t.recorder_times_s();
        let want = [1000.0, 0.54, 1.01, 1.51];
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() < 1e-9, "{got:?}");
        }
        assert!((t.sender_offset_s() + 999.99).abs() < 1e-9);
        let plain = ForceTable { recv_s: None, ..t };
        assert_eq!(plain.recorder_times_s(), plain.timestamp_s);
        assert_eq!(plain.sender_offset_s(), 0.0);
    }

    #[test]
    fn layouts_round_trip_and_reject_bad_packets() {
        let l = ForceLayout::parse("counter,fz,fx").unwrap();
        let s = ForceSample {
            timestamp_s: 3.0,
            values: [1.0, 0.0, -2.0, 0.0, 0.0, 0.0],
        };
        let b = l.encode(&s, 3);
        assert_eq!(l.decode(&b).unwrap(), s);
        assert!(l.decode(&b[..16]).is_err());
        let mut nan = b.clone();
        nan[8..16].copy_from_slice(&f64::NAN.to_le_bytes());
        assert!(l.decode(&nan).is_err());
        assert!(ForceLayout::parse("fx,speed").is_err());
    }

    #[test]
    fn a_faulty_stream_is_counted_and_good_samples_kept() {
        let mut rx =
            ForceReceiver::bind("127.0.0.1:0", ForceLayout::default(), Some(1000.0)).unwrap();
        let addr = rx.local_addr().unwrap();
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let layout = ForceLayout::default();
        let pkt = |k: u64| {
            layout.encode(
                &ForceSample {
                    timestamp_s: k as f64 / 1000.0,
                    values: [k as f64, 0.0, 1.0, 0.0, 0.0, 0.0],
                },
                k,
            )
        };
        // 0..100 with 10..15 lost, 20 sent twice, 31 before 30, and three bad datagrams.
        let mut order: Vec<u64> = (0..100).filter(|k| !(10..15).contains(k)).collect();
        let i30 = order.iter().position(|&k| k == 30).unwrap();
        order.swap(i30, i30 + 1);
        let i20 = order.iter().position(|&k| k == 20).unwrap();
        order.insert(i20 + 1, 20);
        for (n, k) in order.iter().enumerate() {
            tx.send_to(&pkt(*k), addr).unwrap();
            if n == 40 {
                tx.send_to(b"garbage", addr).unwrap();
                tx.send_to(&[0u8; 57], addr).unwrap();
                let mut nan = pkt(500);
                nan[8..16].copy_from_slice(&f64::NAN.to_le_bytes());
                tx.send_to(&nan, addr).unwrap();
            }
        }
        let mut got = Vec::new();
        while let Some(r) = rx
            .recv(std::time::Duration::from_millis(300), || 0.0)
            .unwrap()
        {
            got.push(r.sample.values[0] as u64);
        }
        let s = rx.stats();
        assert_eq!(got.len(), 95, "{s:?}");
        assert_eq!(
            (
                s.packets,
                s.kept,
                s.malformed,
                s.duplicates,
                s.reordered,
                s.lost
            ),
            (99, 95, 3, 1, 1, 5)
        );
    }

    #[test]
    fn layouts_name_one_time_field_and_each_axis_once() {
        for (bad, says) in [
            ("fx,fy,fz", "one time field"),
            ("timestamp_s,counter,fz", "one time field"),
            ("timestamp_s,fx,fx_n", "names fx_n twice"),
        ] {
            let e = ForceLayout::parse(bad).unwrap_err().to_string();
            assert!(e.contains(says), "{bad}: {e}");
        }
        assert!(ForceLayout::parse("fz,counter").is_ok());
    }

    /// Sends `times` (seconds) as packets of the default layout to a fresh receiver and
    /// returns the times it kept, in order, and its counts.
    fn received_times(times: &[f64]) -> (Vec<f64>, ReceiveStats) {
        let mut rx =
            ForceReceiver::bind("127.0.0.1:0", ForceLayout::default(), Some(1000.0)).unwrap();
        let addr = rx.local_addr().unwrap();
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let layout = ForceLayout::default();
        for &t in times {
            let s = ForceSample {
                timestamp_s: t,
                values: [0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
            };
            tx.send_to(&layout.encode(&s, 0), addr).unwrap();
        }
        let mut got = Vec::new();
        while let Some(r) = rx
            .recv(std::time::Duration::from_millis(700), || 0.0)
            .unwrap()
        {
            got.push(r.sample.timestamp_s);
        }
        (got, rx.stats())
    }

    #[test]
    fn a_wild_packet_first_or_later_never_decides_the_stream() {
        let genuine: Vec<f64> = (0..100).map(|k| 10.0 + k as f64 / 1000.0).collect();
        // Stamped 5e9 s (plausible as a UNIX time) or 100 s ahead, first or in the middle:
        // every genuine sample is kept and only the wild one refused.
        for wild in [5e9, 110.0] {
            for at in [0, 50] {
                let mut times = genuine.clone();
                times.insert(at, wild);
                let (got, s) = received_times(&times);
                assert_eq!(got, genuine, "wild {wild} at {at}: {s:?}");
                assert_eq!((s.kept, s.rejected, s.lost), (100, 1, 0), "{wild} at {at}");
            }
        }
        // A sender whose clock restarts: the stream follows it after half a window.
        let mut times = genuine.clone();
        times.extend((0..100).map(|k| k as f64 / 1000.0));
        let (got, s) = received_times(&times);
        assert_eq!(got.len() as u64 + s.rejected, 200, "{s:?}");
        assert!(s.rejected <= STREAM_WINDOW as u64 / 2 + 1, "{s:?}");
        assert_eq!(got.last(), Some(&0.099));
        // A stream shorter than the warm-up still arrives (after HOLD_S).
        let (got, _) = received_times(&[1.0, 1.001]);
        assert_eq!(got, vec![1.0, 1.001]);
    }

    #[test]
    fn force_tables_name_bad_cells_and_drop_a_partial_last_line() {
        let dir = std::env::temp_dir().join(format!("vt-force-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("force.csv");
        std::fs::write(&p, "timestamp_s,fz_n,fx_n\n0.0,1,2\n0.001,1.5,2\n0.002,1.").unwrap();
        let t = ForceTable::read(&p).unwrap();
        assert_eq!(t.timestamp_s, vec![0.0, 0.001]);
        assert_eq!(t.values[1], [2.0, 0.0, 1.5, 0.0, 0.0, 0.0]);
        assert!(t.dropped_partial_line && t.present == [true, false, true, false, false, false]);
        std::fs::write(&p, "timestamp_s,fz_n\n0.0,1\n0.001,x\n").unwrap();
        let e = ForceTable::read(&p).unwrap_err();
        assert_eq!(e.line, Some(3));
        assert!(e.to_string().contains("line 3, column `fz_n`"), "{e}");
        // Saved by a spreadsheet, with a byte-order mark: the first column is still found.
        std::fs::write(&p, b"\xEF\xBB\xBFtimestamp_s,fz_n\n0.0,1\n0.001,2\n").unwrap();
        assert_eq!(ForceTable::read(&p).unwrap().timestamp_s, vec![0.0, 0.001]);
        std::fs::write(&p, "time,fz_n\n").unwrap();
        assert!(ForceTable::read(&p)
            .unwrap_err()
            .to_string()
            .contains("timestamp_s"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn junk_of_the_right_length_is_rejected_and_the_counts_stay_right() {
        let mut rx =
            ForceReceiver::bind("127.0.0.1:0", ForceLayout::default(), Some(1000.0)).unwrap();
        let addr = rx.local_addr().unwrap();
        let tx = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let layout = ForceLayout::default();
        let pkt = |t: f64, fx: f64| {
            layout.encode(
                &ForceSample {
                    timestamp_s: t,
                    values: [fx, 0.0, 1.0, 0.0, 0.0, 0.0],
                },
                0,
            )
        };
        // A seeded stream of random 56-byte packets between 200 good ones (0 … 0.199 s).
        let mut state = 0x5EED_u64;
        let mut random = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            state
        };
        let mut junk = 0;
        for k in 0..200u64 {
            tx.send_to(&pkt(k as f64 / 1000.0, 1.0), addr).unwrap();
            if k % 20 == 10 {
                let bytes: Vec<u8> = (0..7).flat_map(|_| random().to_le_bytes()).collect();
                tx.send_to(&bytes, addr).unwrap();
                // Timestamps of 1e300, before zero, far behind the stream, and a force of 1e9.
                for bad in [
                    pkt(1e300, 1.0),
                    pkt(-1.0, 1.0),
                    pkt(5000.0, 1.0),
                    pkt(0.1, 1e9),
                ] {
                    tx.send_to(&bad, addr).unwrap();
                }
                junk += 5;
            }
        }
        let mut got = Vec::new();
        while let Some(r) = rx
            .recv(std::time::Duration::from_millis(300), || 0.0)
            .unwrap()
        {
            got.push(r.sample);
        }
        let s = rx.stats();
        assert!(got.iter().all(plausible), "{s:?}");
        assert_eq!(s.packets, 200 + junk);
        assert_eq!(s.kept, 200, "{s:?}");
        assert_eq!(s.malformed + s.rejected + s.duplicates, junk, "{s:?}");
        assert_eq!(s.lost, 0, "{s:?}");
    }

    #[test]
    fn a_force_table_with_an_implausible_cell_names_its_row() {
        let d = std::env::temp_dir().join(format!("visuotact-force-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join("f.csv");
        std::fs::write(&p, "timestamp_s,fz_n\n0.0,1.0\n1e300,2.0\n").unwrap();
        let e = ForceTable::read(&p).unwrap_err().to_string();
        assert!(e.contains("line 3, column `timestamp_s`"), "{e}");
        std::fs::write(&p, "timestamp_s,fz_n\n0.0,1.0\n0.1,-3e7\n").unwrap();
        let e = ForceTable::read(&p).unwrap_err().to_string();
        assert!(e.contains("line 3, column `fz_n`"), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }
}

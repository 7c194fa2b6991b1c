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

impl ForceField {
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

impl ForceLayout {
    /// Parses a comma-separated field list, e.g. `counter,fx,fy,fz,tx,ty,tz`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let fields: Result<Vec<ForceField>, String> = s
            .split(',')
            .map(|p| {
                ForceField::from_name(p.trim())
                    .ok_or_else(|| format!("unknown force field {:?}", p.trim()))
            })
            .collect();
        let fields = fields?;
        if fields.is_empty() {
            return Err("the force layout is empty".into());
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
    pub fn decode(&self, bytes: &[u8]) -> Result<ForceSample, String> {
        if bytes.len() != self.packet_len() {
            return Err(format!(
                "packet of {} bytes, expected {}",
                bytes.len(),
                self.packet_len()
            ));
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
                return Err(format!("field {} is not a finite number", f.name()));
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

#[cfg(test)]
mod tests {
    use super::*;

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
}

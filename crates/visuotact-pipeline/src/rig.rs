//! The simulated rigs `record` drives on its own clock (`sim:cone`, whose JR3 streams over UDP
//! to the force receiver, and `sim:iats`). With the `sim` feature they are the simulator's;
//! without it there are none — [`Rig`] has no value, a `sim:` source is refused with
//! [`NO_SIMULATOR`], and the recorder carries no simulator.

use std::time::Instant;

use visuotact_io::force::ForceLayout;

/// Why a `sim:` source is refused in a build without the simulator.
#[cfg_attr(
    feature = "sim",
    allow(dead_code, reason = "read only without the `sim` feature")
)]
pub(crate) const NO_SIMULATOR: &str =
    "this build has no simulator (visuotact-pipeline's `sim` feature is off)";

/// Where and when the simulated JR3 streams (`sim:cone` with a UDP force source).
#[cfg_attr(
    not(feature = "sim"),
    allow(dead_code, reason = "read only where a simulator exists")
)]
pub(crate) struct Jr3Stream<'a> {
    /// Destination address.
    pub(crate) addr: &'a str,
    pub(crate) layout: ForceLayout,
    pub(crate) rate_hz: f64,
    pub(crate) seed: u64,
    /// Time zero of the rig.
    pub(crate) clock: Instant,
    /// First and last sample times, s.
    pub(crate) t_from: f64,
    pub(crate) t_end: f64,
}

#[cfg(feature = "sim")]
pub(crate) use with_sim::*;
#[cfg(not(feature = "sim"))]
pub(crate) use without_sim::*;

#[cfg(feature = "sim")]
mod with_sim {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use std::thread::JoinHandle;
    use std::time::Duration;

    use visuotact_io::force::ForceSample;
    use visuotact_io::source::SourceSpec;
    use visuotact_sim::jr3::{Jr3, Jr3Config};
    pub(crate) use visuotact_sim::rig::{frame_seed, SimRig as Rig};
    use visuotact_sim::{MAX_FRAMES, MAX_REFERENCES};

    use super::Jr3Stream;
    use crate::record::{RecordConfig, RecordError};

    /// The simulated rigs' limits on a recording's settings.
    pub(crate) fn check_limits(cfg: &RecordConfig) -> Result<(), RecordError> {
        if cfg.references > MAX_REFERENCES {
            return Err(RecordError::Config(format!(
                "references {}: a simulated rig writes at most {} reference frames",
                cfg.references, MAX_REFERENCES
            )));
        }
        // The simulated touch rig draws its touches up front.
        let sim = matches!(cfg.source, SourceSpec::Sim(_));
        if sim && cfg.max_frames.is_some_and(|n| n > MAX_FRAMES) {
            return Err(RecordError::Config(format!(
                "max_frames {}: a simulated rig records at most {} frames",
                cfg.max_frames.unwrap_or_default(),
                MAX_FRAMES
            )));
        }
        Ok(())
    }

    /// Sends the simulated JR3 stream of the cone rig, paced in real time, until `stop`.
    pub(crate) fn spawn_jr3(
        rig: &Rig,
        j: Jr3Stream<'_>,
        stop: Arc<AtomicBool>,
    ) -> Result<Option<JoinHandle<u64>>, RecordError> {
        let Rig::Cone { cfg, press, rest_s } = rig else {
            return Ok(None);
        };
        let (cfg, press, rest_s) = (*cfg, *press, *rest_s);
        let sock = std::net::UdpSocket::bind("127.0.0.1:0")?;
        sock.connect(j.addr).map_err(|e| {
            std::io::Error::new(
                e.kind(),
                format!("simulated force sensor: cannot address {}: {e}", j.addr),
            )
        })?;
        let jr3_cfg = Jr3Config {
            rate_hz: j.rate_hz,
            ..Jr3Config::JR3_1KHZ
        };
        jr3_cfg.validate()?;
        let Jr3Stream {
            layout,
            rate_hz,
            seed,
            clock,
            t_from,
            t_end,
            ..
        } = j;
        Ok(Some(std::thread::spawn(move || {
            let mut jr3 = Jr3::new(jr3_cfg, seed ^ 0x4A33);
            let mut sent = 0u64;
            let mut i = (t_from * rate_hz).ceil() as u64;
            loop {
                let t = i as f64 / rate_hz;
                if t > t_end || stop.load(Ordering::Relaxed) {
                    break;
                }
                let due = Duration::from_secs_f64(t);
                let now = clock.elapsed();
                if due > now + Duration::from_micros(300) {
                    std::thread::sleep(due - now);
                }
                let load = Rig::cone_load(&cfg, &press, rest_s, t);
                let s = ForceSample {
                    timestamp_s: t,
                    values: jr3.sample(load.components_n()),
                };
                if sock.send(&layout.encode(&s, i)).is_ok() {
                    sent += 1;
                }
                i += 1;
            }
            sent
        })))
    }
}

#[cfg(not(feature = "sim"))]
mod without_sim {
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;
    use std::thread::JoinHandle;

    use visuotact_image::RgbImage;

    use super::Jr3Stream;
    use crate::record::{RecordConfig, RecordError};

    /// No limits to check: without a simulator a `sim:` source is refused and no reference
    /// frames are drawn.
    pub(crate) fn check_limits(_: &RecordConfig) -> Result<(), RecordError> {
        Ok(())
    }

    /// No simulated rig: this type has no value, so no code path that needs one can run.
    pub(crate) enum Rig {}

    impl Rig {
        pub(crate) fn reference(&self, _: u64) -> Result<RgbImage, RecordError> {
            match *self {}
        }

        pub(crate) fn label_columns(&self) -> Vec<&'static str> {
            match *self {}
        }

        pub(crate) fn total_s(&self, _: f64) -> f64 {
            match *self {}
        }

        pub(crate) fn frame(
            &self,
            _: usize,
            _: f64,
            _: u64,
        ) -> Result<(RgbImage, Vec<f64>), crate::source::SourceError> {
            match *self {}
        }
    }

    /// A frame's seed; only a rig reads it, and there is none.
    pub(crate) fn frame_seed(seed: u64, _: u64) -> u64 {
        seed
    }

    pub(crate) fn spawn_jr3(
        rig: &Rig,
        _: Jr3Stream<'_>,
        _: Arc<AtomicBool>,
    ) -> Result<Option<JoinHandle<u64>>, RecordError> {
        match *rig {}
    }
}

#[cfg(all(test, not(feature = "sim")))]
mod tests {
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    use crate::record::{record, RecordConfig};

    #[test]
    fn a_simulated_rig_is_refused_without_the_simulator_and_nothing_is_written() {
        let dir = std::env::temp_dir().join(format!("visuotact-no-sim-{}", std::process::id()));
        let cfg = RecordConfig {
            source: "sim:cone".into(),
            output: dir.clone(),
            ..RecordConfig::default()
        };
        let stop = Arc::new(AtomicBool::new(false));
        let err = record(&cfg, None, &stop, &mut |_| {}).unwrap_err();
        assert!(
            err.to_string()
                .contains("sim:cone: this build has no simulator"),
            "{err}"
        );
        assert!(!dir.exists());
    }
}

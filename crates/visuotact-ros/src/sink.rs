//! A live run into a bag: [`McapSink`] is a [`Sink`] of the live runner that writes each
//! estimate as ROS 2 messages ([`crate::topics`]), stamped on the wall clock (the time the sink
//! was made plus the run's capture time).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use visuotact_image::RgbImage;
use visuotact_pipeline::live::MarkerView;
use visuotact_pipeline::runner::Sink;
use visuotact_pipeline::LiveEstimate;

use crate::bag::{Bag, BagConfig};
use crate::topics::{ns_from_s, write_frame, FrameMessages, MarkerPoint, RosConfig};
use crate::RosError;

/// Writes a live run's estimates into an MCAP bag.
pub struct McapSink {
    bag: Bag,
    cfg: RosConfig,
    origin_ns: u64,
    markers: Vec<MarkerPoint>,
    error: Option<RosError>,
}

impl McapSink {
    /// A bag at `path` ([`Bag::create`]); stamps count from now.
    pub fn create(path: &Path, cfg: RosConfig, bag: &BagConfig) -> Result<Self, RosError> {
        cfg.validate()?;
        let origin_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
        Ok(Self {
            bag: Bag::create(path, bag)?,
            cfg,
            origin_ns,
            markers: Vec::new(),
            error: None,
        })
    }

    /// Closes the bag; the first write error of the run, if any, instead.
    pub fn finish(self) -> Result<(PathBuf, u64), RosError> {
        let n = self.bag.messages();
        let path = self.bag.finish()?;
        match self.error {
            Some(e) => Err(e),
            None => Ok((path, n)),
        }
    }

    fn write(
        &mut self,
        e: &LiveEstimate,
        markers: Option<&[MarkerView]>,
        image: &RgbImage,
    ) -> Result<(), RosError> {
        if let Some(m) = markers {
            self.markers.clear();
            self.markers.extend(m.iter().map(|v| MarkerPoint {
                x_px: v.x,
                y_px: v.y,
                dx_px: if v.ok { v.dx } else { f32::NAN },
                dy_px: if v.ok { v.dy } else { f32::NAN },
                found: v.ok,
            }));
        }
        let png = if self.cfg.images {
            Some(crate::png_from_rgb(image)?)
        } else {
            None
        };
        let values = vec![
            ("latency_ms".to_string(), format!("{:.3}", e.latency_ms)),
            ("dropped_frames".to_string(), e.dropped_frames.to_string()),
        ];
        let frame = FrameMessages {
            stamp_ns: self.origin_ns + ns_from_s(e.timestamp_s),
            targets: &e.targets,
            contact: Some(e.contact),
            measured: None,
            markers: markers.map(|_| &self.markers[..]),
            png,
            health: Some((&e.health, values)),
        };
        write_frame(&mut self.bag, &self.cfg, frame)
    }
}

impl Sink for McapSink {
    fn wants_markers(&self) -> bool {
        true
    }

    fn send(
        &mut self,
        estimate: &LiveEstimate,
        _json: &str,
        markers: Option<&[MarkerView]>,
        image: &Arc<RgbImage>,
    ) -> ControlFlow<()> {
        match self.write(estimate, markers, image) {
            Ok(()) => ControlFlow::Continue(()),
            Err(e) => {
                self.error = Some(e);
                ControlFlow::Break(())
            }
        }
    }
}

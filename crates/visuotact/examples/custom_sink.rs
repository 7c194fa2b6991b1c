//! A sink of your own in the live runner: here, a line each time a touch starts or ends, with
//! the largest marker motion, on the simulated 117-marker membrane (no camera needed). A ROS
//! node would publish in `frame` instead.
//!
//! `cargo run --release -p visuotact --example custom_sink`

use std::ops::ControlFlow;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use visuotact::pipeline::runner::{run, RunConfig};
use visuotact::pipeline::sink::{FrameSink, SinkError, SinkFrame};
use visuotact::sim::iats::{render, IatsConfig, Touch};
use visuotact::vision::calibration::{calibrate, Preset};
use visuotact::{Estimator, LiveConfig, LiveEstimator};

/// Prints when contact starts and ends; stops the run after `touches` touches.
struct Touches {
    in_contact: bool,
    seen: usize,
    touches: usize,
}

impl FrameSink for Touches {
    fn frame(&mut self, f: &SinkFrame<'_>) -> Result<ControlFlow<()>, SinkError> {
        let Some(e) = f.estimate else {
            return Ok(ControlFlow::Continue(()));
        };
        if e.contact != self.in_contact {
            self.in_contact = e.contact;
            let what = if e.contact { "touch" } else { "released" };
            println!(
                "frame {:>4}: {what}, largest marker motion {:.1} px, {} markers ok, {} lost",
                e.index, e.max_displacement_px, e.health.ok, e.health.lost
            );
            if !e.contact {
                self.seen += 1;
            }
        }
        Ok(if self.seen >= self.touches {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        })
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // Calibrate on two contact-free frames of the simulated membrane.
    let cfg = IatsConfig::SEED000;
    let rest = [
        render(&cfg, &Touch::default(), 1)?.0,
        render(&cfg, &Touch::default(), 2)?.0,
    ];
    let (sensor, _) = calibrate([("a", &rest[0]), ("b", &rest[1])], &Preset::Iats.config())?;
    let mut live = LiveEstimator::new(
        Estimator::from_sensor(sensor)?,
        vec![],
        &LiveConfig::default(),
    )?;
    let run_cfg = RunConfig {
        source: "sim:iats".into(),
        unpaced: true,
        ..RunConfig::default()
    };
    let mut sink = Touches {
        in_contact: false,
        seen: 0,
        touches: 3,
    };
    let stop = Arc::new(AtomicBool::new(false));
    run(&mut live, &run_cfg, &stop, &mut [&mut sink], |w| {
        eprintln!("{w}")
    })?;
    Ok(())
}

//! Slip onsets on the simulator: `cargo run --release -p visuotact-experiments --example
//! slip_onset [SEEDS]` prints, per grasp kind, how many grasps end in `slip`, the first alarm
//! against the truth, and the onset latency of detected slips, with the built-in detector.

use visuotact_experiments::slipcheck::check_grasp;
use visuotact_pipeline::slip::{SlipDetector, SlipState};
use visuotact_sim::protocol::GraspKind;
use visuotact_sim::zoo::ZooConfig;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let det = SlipDetector::default();
    let cfg = ZooConfig::GELSIGHT;
    println!("kind\tgrasps\tending in slip\tany alarm\tmedian latency (frames)\tlatencies");
    for kind in GraspKind::ALL {
        let mut out = Vec::new();
        for seed in 0..seeds {
            out.push(check_grasp(&cfg, kind, 100, seed, &det)?);
        }
        let ending = out
            .iter()
            .filter(|o| o.final_state == SlipState::Slip)
            .count();
        let alarms = out.iter().filter(|o| o.first_alarm.is_some()).count();
        let mut lat: Vec<i64> = out
            .iter()
            .filter_map(|o| Some(o.first_alarm? as i64 - o.slip_frame? as i64))
            .collect();
        lat.sort_unstable();
        let med = lat
            .get(lat.len() / 2)
            .map_or("-".to_string(), ToString::to_string);
        println!(
            "{kind:?}\t{}\t{ending}\t{alarms}\t{med}\t{lat:?}",
            out.len()
        );
    }
    Ok(())
}

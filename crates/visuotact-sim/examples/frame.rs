//! Writes one simulated frame as a binary PPM, to look at:
//! `cargo run -p visuotact-sim --example frame -- iats OUT.ppm X_MM Y_MM DEPTH_MM [SHEAR_X SHEAR_Y]`
//! `cargo run -p visuotact-sim --example frame -- cone OUT.ppm FORCE_N AZIMUTH_DEG`

use std::io::Write;

use visuotact_sim::cone::{ConeConfig, ConeLoad};
use visuotact_sim::iats::{IatsConfig, Touch};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let num = |i: usize, d: f64| args.get(i).map_or(d, |s| s.parse().expect("number"));
    let img = match args.get(1).map(String::as_str) {
        Some("cone") => {
            let load = ConeLoad {
                force_n: num(3, 0.0),
                elevation_rad: 30f64.to_radians(),
                azimuth_rad: num(4, 0.0).to_radians(),
                pressure_kpa: 4.0,
                torque_nmm: 0.0,
            };
            visuotact_sim::cone::render(&ConeConfig::SEED001, &load, 1)
                .expect("valid load")
                .0
        }
        _ => {
            let touch = Touch {
                x_mm: num(3, 30.0),
                y_mm: num(4, 22.5),
                depth_mm: num(5, 0.0),
                shear_x_mm: num(6, 0.0),
                shear_y_mm: num(7, 0.0),
            };
            visuotact_sim::iats::render(&IatsConfig::SEED000, &touch, 1)
                .expect("valid touch")
                .0
        }
    };
    let mut f = std::fs::File::create(args.get(2).expect("output path")).expect("create");
    write!(f, "P6\n{} {}\n255\n", img.width(), img.height()).expect("write");
    f.write_all(img.as_slice()).expect("write");
}

//! The sensor zoo: marker sensors the vision pipeline was not written for, to test it on.
//!
//! Three families, each a preset and a generator of variants whose every parameter is drawn
//! from a documented range ([`ZooConfig::variant`]), so that tests run on sensors nobody tuned:
//! - [`ZooKind::Tactip`]: a hemispherical tip with a hexagonal array of white pins seen from
//!   inside through a wide-angle lens, in a circular view; optionally binarised, like published
//!   TacTip data sets.
//! - [`ZooKind::Gelsight`]: a flat gel with a grid of small dark dots on a bright, unevenly lit
//!   surface whose colour changes with its slope under a press (the coloured LEDs).
//! - [`ZooKind::Dots`]: a flat gel with a random dot pattern.
//!
//! The skin model is the same for all (physics-inspired; every parameter in [`ZooConfig`]).
//! Positions on the skin are chart coordinates `(u, v)` in mm, centred on the marker field, u
//! along the image's x and v along its y (on a dome, arc lengths from the apex). A spherical tip
//! of radius `R` pressed to depth `d` makes a Hertzian contact of radius `a = sqrt(R d)`; at
//! distance `r` from it:
//! - the skin moves along its normal by `d · h(r/a)`, Hertz's half-space profile (`1 − ρ²/2`
//!   inside the contact, `((2 − ρ²) asin(1/ρ) + sqrt(ρ² − 1)) / π` outside) cut off beyond the
//!   contact by `exp(−(r − a)/t)`, `t` the skin's thickness;
//! - along the skin it moves radially by `κ d φ(r)`, `φ = r/a` inside and `(a/r) exp(−(r − a)/t)`
//!   outside (κ > 0: a gel squeezed outwards; κ < 0: a membrane pulled in);
//! - it follows the tip's sideways drag and twist times `χ(r)`, 1 inside the contact and
//!   `exp(−(r − a)/t)` outside.
//!
//! Each marker is a circle painted on the skin: its boundary points are moved by the field,
//! placed on the surface (a plane at the camera distance, or a dome whose apex faces the camera)
//! and projected through the pinhole camera with radial distortion, so the marker shifts, grows
//! as it comes closer and becomes an ellipse where the skin tilts. The projected outline is
//! filled as a polygon whose exact area and centroid are the truth ([`ZooMarker`]).
//!
//! ```
//! use visuotact_sim::zoo::{render, ZooConfig, ZooKind, ZooTouch};
//! let cfg = ZooConfig::variant(ZooKind::Tactip, 3);
//! let touch = ZooTouch { x_mm: 2.0, y_mm: -1.0, depth_mm: 3.0, ..ZooTouch::default() };
//! let (img, truth) = render(&cfg, &touch, 7).unwrap();
//! assert_eq!((img.width(), img.height()), (cfg.camera.width, cfg.camera.height));
//! assert!(truth.len() > 200);
//! ```

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use visuotact_image::RgbImage;

use crate::camera::Camera;
use crate::pattern::{frame_from_coverage_lit, Look};
use crate::render::{clear_crowded, ring_area_centroid, squeezed, Canvas, ConvexPolygon};

/// The zoo's sensor families.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ZooKind {
    /// A TacTip-like hemispherical tip with a hexagonal pin array.
    Tactip,
    /// A GelSight-like flat gel with a dark-dot grid.
    Gelsight,
    /// A flat gel with a random dot pattern.
    Dots,
    /// The TacTip tip as published data sets store it: 128 × 128, binarised, pins 2–4 px
    /// (variant N is tactip's variant N on that image).
    TactipSmall,
}

visuotact_image::names_from_str!(ZooKind, "zoo sensor");

impl ZooKind {
    /// The names [`ZooKind::from_name`] and `FromStr` read (each is also what `name` writes,
    /// where the type has one).
    pub const NAMES: &'static [&'static str] = &["tactip", "tactip-small", "gelsight", "dots"];

    /// Every family.
    pub const ALL: [ZooKind; 4] = [
        ZooKind::Tactip,
        ZooKind::TactipSmall,
        ZooKind::Gelsight,
        ZooKind::Dots,
    ];

    /// The name `simulate --sensor` takes.
    pub fn name(self) -> &'static str {
        match self {
            ZooKind::Tactip => "tactip",
            ZooKind::TactipSmall => "tactip-small",
            ZooKind::Gelsight => "gelsight",
            ZooKind::Dots => "dots",
        }
    }

    /// The family called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The family's preset.
    pub fn preset(self) -> ZooConfig {
        match self {
            ZooKind::Tactip => ZooConfig::TACTIP,
            ZooKind::TactipSmall => ZooConfig::TACTIP_SMALL,
            ZooKind::Gelsight => ZooConfig::GELSIGHT,
            ZooKind::Dots => ZooConfig::DOTS,
        }
    }
}

/// The skin's shape at rest.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Surface {
    /// A plane across the optical axis at the camera distance.
    Flat,
    /// A hemisphere seen from its centre side, apex on the optical axis.
    Dome,
}

/// How markers are laid out on the skin.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Arrangement {
    /// A square grid.
    Grid,
    /// A hexagonal array (rows half a pitch apart, √3/2 pitch between rows).
    Hex,
    /// Random dots at least 0.8 pitch apart, at about the density of a grid of that pitch.
    Random,
    /// A centre dot and concentric rings of dots one pitch apart, about a pitch between dots.
    DotRings,
}

/// Every geometric, mechanical and optical parameter of a zoo sensor.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ZooConfig {
    /// The skin's shape.
    pub surface: Surface,
    /// Dome radius, mm (dome only).
    pub dome_radius_mm: f64,
    /// Marker layout.
    pub arrangement: Arrangement,
    /// Width of the marker field, mm; on a dome, the diameter of the field in arc length.
    pub field_width_mm: f64,
    /// Height of the marker field, mm (flat only).
    pub field_height_mm: f64,
    /// Marker spacing, mm.
    pub pitch_mm: f64,
    /// Rotation of the pattern, degrees.
    pub pattern_angle_deg: f64,
    /// Standard deviation of the painting's random misplacement of each marker, mm.
    pub position_jitter_mm: f64,
    /// Marker radius, mm.
    pub marker_radius_mm: f64,
    /// Seed of the random pattern and the misplacements.
    pub layout_seed: u64,
    /// Thickness of the soft body the markers sit on, mm: how far beyond the contact the skin
    /// follows the tip (a gel layer on glass: the gel; a skin over a gel-filled tip: the gel's
    /// depth).
    pub skin_thickness_mm: f64,
    /// Radial motion along the skin per mm of depth (κ; negative: towards the contact).
    pub radial_coupling: f64,
    /// Radius of the spherical tip, mm.
    pub tip_radius_mm: f64,
    /// The skin's limit: deepest indentation, mm.
    pub max_depth_mm: f64,
    /// Distance from the camera to the skin (flat) or to the dome's apex, mm.
    pub camera_distance_mm: f64,
    /// The camera.
    pub camera: Camera,
    /// A circular view: pixels outside the dome's rim are black (dome only).
    pub aperture: bool,
    /// Colours, vignetting and noise.
    pub look: Look,
    /// Brightness change from the image centre to its right and bottom edges (uneven lighting).
    pub light_gradient: [f32; 2],
    /// Colour change of the background per unit slope of the skin (coloured side lights; flat
    /// skins only).
    pub shading: f32,
    /// Output black and white only, thresholded halfway between background and marker.
    pub binarise: bool,
    /// Optical blur, pixels (Gaussian σ).
    pub blur_px: f64,
}

impl ZooConfig {
    /// A TacTip-like tip: a 20 mm hemisphere with ≈ 330 white pins in a hexagonal array seen
    /// from inside by a wide-angle camera, ≈ 20 px apart, in a circular view.
    pub const TACTIP: Self = Self {
        surface: Surface::Dome,
        dome_radius_mm: 20.0,
        arrangement: Arrangement::Hex,
        field_width_mm: 48.0,
        field_height_mm: 48.0,
        pitch_mm: 2.5,
        pattern_angle_deg: 0.0,
        position_jitter_mm: 0.03,
        marker_radius_mm: 0.75,
        layout_seed: 1,
        skin_thickness_mm: 8.0,
        radial_coupling: -0.15,
        tip_radius_mm: 6.0,
        max_depth_mm: 6.0,
        camera_distance_mm: 28.0,
        camera: Camera {
            width: 640,
            height: 480,
            fx_px: 192.0,
            fy_px: 192.0,
            cx_px: 319.5,
            cy_px: 239.5,
            k1: -0.1,
            k2: 0.01,
        },
        aperture: true,
        look: Look {
            background: [12.0, 12.0, 14.0],
            marker: [235.0, 235.0, 230.0],
            noise_sigma: 3.0,
            vignetting: 0.25,
        },
        light_gradient: [0.0, 0.0],
        shading: 0.0,
        binarise: false,
        blur_px: 0.7,
    };

    /// [`ZooConfig::TACTIP`] as published TacTip data sets store it: 128 × 128 pixels,
    /// binarised, ≈ 330 pins 2–4 px across and ≈ 5 px apart.
    pub const TACTIP_SMALL: Self = Self {
        camera: Camera {
            width: 128,
            height: 128,
            fx_px: 51.2,
            fy_px: 51.2,
            cx_px: 63.5,
            cy_px: 63.5,
            k1: -0.1,
            k2: 0.01,
        },
        binarise: true,
        blur_px: 0.4,
        ..Self::TACTIP
    };

    /// A GelSight-Mini-like gel: 10 × 8 dark dots 2 mm apart on a bright, unevenly lit gel,
    /// 320×240 like the Mini's stream, 2.5 mm of gel pressed up to 1.5 mm.
    pub const GELSIGHT: Self = Self {
        surface: Surface::Flat,
        dome_radius_mm: 20.0,
        arrangement: Arrangement::Grid,
        field_width_mm: 18.0,
        field_height_mm: 14.0,
        pitch_mm: 2.0,
        pattern_angle_deg: 1.0,
        position_jitter_mm: 0.02,
        marker_radius_mm: 0.35,
        layout_seed: 1,
        skin_thickness_mm: 2.5,
        radial_coupling: 0.2,
        tip_radius_mm: 4.0,
        max_depth_mm: 1.5,
        camera_distance_mm: 16.0,
        camera: Camera {
            width: 320,
            height: 240,
            fx_px: 224.0,
            fy_px: 224.0,
            cx_px: 159.5,
            cy_px: 119.5,
            k1: -0.05,
            k2: 0.0,
        },
        aperture: false,
        look: Look {
            background: [190.0, 178.0, 160.0],
            marker: [35.0, 35.0, 45.0],
            noise_sigma: 2.5,
            vignetting: 0.25,
        },
        light_gradient: [0.12, -0.08],
        shading: 0.6,
        binarise: false,
        blur_px: 0.7,
    };

    /// A random dot pattern: bright dots about 2.5 mm apart on a dark 40 × 30 mm gel.
    pub const DOTS: Self = Self {
        surface: Surface::Flat,
        dome_radius_mm: 20.0,
        arrangement: Arrangement::Random,
        field_width_mm: 40.0,
        field_height_mm: 30.0,
        pitch_mm: 2.5,
        pattern_angle_deg: 0.0,
        position_jitter_mm: 0.0,
        marker_radius_mm: 0.55,
        layout_seed: 1,
        skin_thickness_mm: 3.0,
        radial_coupling: 0.1,
        tip_radius_mm: 6.0,
        max_depth_mm: 2.0,
        camera_distance_mm: 30.0,
        camera: Camera::WEBCAM_640X480,
        aperture: false,
        look: Look {
            background: [25.0, 25.0, 30.0],
            marker: [200.0, 220.0, 90.0],
            noise_sigma: 3.0,
            vignetting: 0.2,
        },
        light_gradient: [0.0, 0.0],
        shading: 0.0,
        binarise: false,
        blur_px: 0.6,
    };

    /// A sensor of family `kind` with parameters drawn from the family's ranges by `seed`
    /// (seed 0: the preset). The ranges (uniform):
    ///
    /// | | tactip | gelsight | dots |
    /// |---|---|---|---|
    /// | dome radius | 17–23 mm | – | – |
    /// | pitch | 0.11–0.15 × dome radius | 1.6–2.4 mm | 2–3 mm |
    /// | marker radius | 0.25–0.36 pitch | 0.15–0.25 pitch | 0.18–0.3 pitch |
    /// | field | 2.1–2.5 × dome radius across | 8–12 × 6–9 pitches | 14–17 × 10–13 pitches |
    /// | pattern angle, misplacement | 0–60°, 0–5 % pitch | ±3°, 0–3 % pitch | –, – |
    /// | soft body thickness | 0.3–0.6 × dome radius (gel-filled) | 1.5–4 mm (gel on glass) | 2–4 mm |
    /// | radial coupling κ | −0.3…0.3 | −0.15…0.4 | −0.2…0.3 |
    /// | tip radius | 4–10 mm | 2–8 mm | 3–10 mm |
    /// | deepest press | 4–6 mm | 0.4–0.6 × skin | 0.4–0.6 × skin |
    /// | camera distance | dome + 5–12 mm | 12–20 mm | 25–40 mm |
    /// | k1 (barrel) | −0.15…−0.03 | −0.1…0 | −0.1…0 |
    /// | image | 640×480, rim at 0.42–0.49 height | 320×240, field fills 75–92 % | 640×480, fills 75–92 % |
    /// | look | white-ish pins on near-black | dark dots on a tinted bright gel, gradient ±0.2, shading 0.3–0.8 | bright or dark dots (half each) |
    ///
    /// Binarised output (`binarise`, as published TacTip data sets) is a setting of its own, not
    /// drawn: it changes what any centroid can measure (pixel digitisation). `tactip-small`
    /// draws tactip's parameters onto a binarised 128 × 128 image.
    /// | noise σ, vignetting, blur | 1–5, 0.05–0.4, 0.3–1 px | 1–4, 0.1–0.3, 0.4–1 px | 1–5, 0.05–0.3, 0.3–1 px |
    pub fn variant(kind: ZooKind, seed: u64) -> Self {
        let mut c = kind.preset();
        if seed == 0 {
            return c;
        }
        // The small tip draws what the tip draws (only its image differs).
        let family = match kind {
            ZooKind::TactipSmall => ZooKind::Tactip,
            other => other,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7A00_0000 ^ (family as u64) << 40);
        let mut u = |lo: f64, hi: f64| rng.random_range(lo..=hi);
        c.layout_seed = seed;
        match kind {
            ZooKind::Tactip => c.draw_tactip(&mut u),
            ZooKind::TactipSmall => {
                c.camera = ZooConfig::TACTIP_SMALL.camera;
                c.draw_tactip(&mut u);
                // A 128-line image is a larger one shrunk about 4×: its blur shrinks with it
                // (0.3–0.5 px where the tip draws 0.3–1 px), and its pins are 2–4 px across
                // about 6 px apart as in published sets (0.20–0.30 pitch in radius where the
                // tip draws 0.25–0.36).
                c.blur_px = 0.3 + (c.blur_px - 0.3) * (0.2 / 0.7);
                let radius = c.marker_radius_mm / c.pitch_mm;
                c.marker_radius_mm = c.pitch_mm * (0.2 + (radius - 0.25) * (0.1 / 0.11));
            }
            ZooKind::Gelsight => c.draw_gelsight(&mut u),
            ZooKind::Dots => c.draw_dots(&mut u),
        }
        c
    }

    /// Sets the focal length so that the dome's rim lies at `rim` × the image height from the
    /// centre, keeping the distortion monotonic out to the rim.
    fn fit_dome_in_view(&mut self, rim: f64) {
        let r = self.rim_ray();
        let r2 = r * r;
        // d(r·D(r))/dr = 1 + 3 k1 r² + 5 k2 r⁴ ≥ 0.3 out to the rim.
        self.camera.k1 = self
            .camera
            .k1
            .max(-(0.7 + 5.0 * self.camera.k2 * r2 * r2) / (3.0 * r2));
        let d = 1.0 + self.camera.k1 * r2 + self.camera.k2 * r2 * r2;
        let f = rim * self.camera.height as f64 / (r * d);
        self.camera.fx_px = f;
        self.camera.fy_px = f;
    }

    /// Sets the focal length so that the marker field spans `fill` of the image's width or
    /// height, whichever is tighter.
    fn fit_flat_in_view(&mut self, fill: f64) {
        let half_w = 0.5 * self.field_width_mm / self.camera_distance_mm;
        let half_h = 0.5 * self.field_height_mm / self.camera_distance_mm;
        let cam = &mut self.camera;
        let d = |x: f64| 1.0 + cam.k1 * x * x + cam.k2 * x.powi(4);
        let fw = fill * 0.5 * cam.width as f64 / (half_w * d(half_w));
        let fh = fill * 0.5 * cam.height as f64 / (half_h * d(half_h));
        cam.fx_px = fw.min(fh);
        cam.fy_px = cam.fx_px;
    }

    /// The normalised ray radius of the dome's rim (the field's edge plus half a pitch).
    fn rim_ray(&self) -> f64 {
        let rd = self.dome_radius_mm;
        let theta = (0.5 * self.field_width_mm + 0.5 * self.pitch_mm) / rd;
        let zc = self.camera_distance_mm - rd;
        rd * theta.sin() / (zc + rd * theta.cos())
    }

    /// A TacTip-like dome: its geometry, camera and look drawn with `u(lo, hi)`.
    fn draw_tactip(&mut self, u: &mut impl FnMut(f64, f64) -> f64) {
        self.dome_radius_mm = u(17.0, 23.0);
        self.pitch_mm = u(0.11, 0.15) * self.dome_radius_mm;
        self.marker_radius_mm = u(0.25, 0.36) * self.pitch_mm;
        self.field_width_mm = u(2.1, 2.5) * self.dome_radius_mm;
        self.field_height_mm = self.field_width_mm;
        self.pattern_angle_deg = u(0.0, 60.0);
        self.position_jitter_mm = u(0.0, 0.05) * self.pitch_mm;
        // The skin is backed by the gel filling the tip: the soft body is deep.
        self.skin_thickness_mm = u(0.3, 0.6) * self.dome_radius_mm;
        self.radial_coupling = u(-0.3, 0.3);
        self.tip_radius_mm = u(4.0, 10.0);
        self.max_depth_mm = u(4.0, 6.0);
        self.camera_distance_mm = self.dome_radius_mm + u(5.0, 12.0);
        self.camera.k1 = u(-0.15, -0.03);
        self.camera.k2 = u(0.0, 0.02);
        let rim = u(0.42, 0.49);
        let grey = u(0.0, 25.0) as f32;
        let white = u(180.0, 255.0) as f32;
        self.look = Look {
            background: [grey, grey, grey + u(0.0, 5.0) as f32],
            marker: [
                white,
                white - u(0.0, 20.0) as f32,
                white - u(0.0, 30.0) as f32,
            ],
            noise_sigma: u(1.0, 5.0) as f32,
            vignetting: u(0.05, 0.4) as f32,
        };
        self.blur_px = u(0.3, 1.0);
        self.fit_dome_in_view(rim);
    }

    /// A GelSight-like flat gel: its geometry, camera and look drawn with `u(lo, hi)`.
    fn draw_gelsight(&mut self, u: &mut impl FnMut(f64, f64) -> f64) {
        self.pitch_mm = u(1.6, 2.4);
        self.marker_radius_mm = u(0.15, 0.25) * self.pitch_mm;
        self.field_width_mm = u(8.0, 12.0).floor() * self.pitch_mm;
        self.field_height_mm = u(6.0, 9.0).floor() * self.pitch_mm;
        self.pattern_angle_deg = u(-3.0, 3.0);
        self.position_jitter_mm = u(0.0, 0.03) * self.pitch_mm;
        self.skin_thickness_mm = u(1.5, 4.0);
        self.radial_coupling = u(-0.15, 0.4);
        self.tip_radius_mm = u(2.0, 8.0);
        self.max_depth_mm = u(0.4, 0.6) * self.skin_thickness_mm;
        self.camera_distance_mm = u(12.0, 20.0);
        self.camera.k1 = u(-0.1, 0.0);
        let fill = u(0.75, 0.92);
        let tint = [u(0.85, 1.0), u(0.85, 1.0), u(0.8, 1.0)];
        let bright = u(150.0, 220.0);
        let dark = u(15.0, 70.0) as f32;
        self.look = Look {
            background: tint.map(|t| (t * bright) as f32),
            marker: [dark, dark, dark + u(0.0, 15.0) as f32],
            noise_sigma: u(1.0, 4.0) as f32,
            vignetting: u(0.1, 0.3) as f32,
        };
        self.light_gradient = [u(-0.2, 0.2) as f32, u(-0.2, 0.2) as f32];
        self.shading = u(0.3, 0.8) as f32;
        self.blur_px = u(0.4, 1.0);
        self.fit_flat_in_view(fill);
    }

    /// A random-dot flat skin: its geometry, camera and look drawn with `u(lo, hi)`.
    fn draw_dots(&mut self, u: &mut impl FnMut(f64, f64) -> f64) {
        self.pitch_mm = u(2.0, 3.0);
        self.marker_radius_mm = u(0.18, 0.3) * self.pitch_mm;
        self.field_width_mm = u(14.0, 17.0) * self.pitch_mm;
        self.field_height_mm = u(10.0, 13.0) * self.pitch_mm;
        self.skin_thickness_mm = u(2.0, 4.0);
        self.radial_coupling = u(-0.2, 0.3);
        self.tip_radius_mm = u(3.0, 10.0);
        self.max_depth_mm = u(0.4, 0.6) * self.skin_thickness_mm;
        self.camera_distance_mm = u(25.0, 40.0);
        self.camera.k1 = u(-0.1, 0.0);
        let fill = u(0.75, 0.92);
        let (lo, hi) = (u(10.0, 50.0) as f32, u(150.0, 240.0) as f32);
        let colour = [u(0.7, 1.0) as f32, u(0.7, 1.0) as f32, u(0.3, 1.0) as f32];
        let (bg, mk) = if u(0.0, 1.0) < 0.5 {
            ([lo, lo, lo], colour.map(|k| k * hi))
        } else {
            (colour.map(|k| k * hi), [lo, lo, lo])
        };
        self.look = Look {
            background: bg,
            marker: mk,
            noise_sigma: u(1.0, 5.0) as f32,
            vignetting: u(0.05, 0.3) as f32,
        };
        self.blur_px = u(0.3, 1.0);
        self.fit_flat_in_view(fill);
    }

    /// Checks the parameters; the message names the bad one.
    pub fn validate(&self) -> Result<(), crate::SimError> {
        self.camera.validate()?;
        for (name, v) in [
            ("field_width_mm", self.field_width_mm),
            ("pitch_mm", self.pitch_mm),
            ("marker_radius_mm", self.marker_radius_mm),
            ("skin_thickness_mm", self.skin_thickness_mm),
            ("tip_radius_mm", self.tip_radius_mm),
            ("max_depth_mm", self.max_depth_mm),
            ("camera_distance_mm", self.camera_distance_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(crate::SimError::out_of_range(name, v, "positive"));
            }
        }
        if !(self.position_jitter_mm.is_finite() && self.position_jitter_mm >= 0.0) {
            return Err(crate::SimError::out_of_range(
                "position_jitter_mm",
                self.position_jitter_mm,
                "≥ 0",
            ));
        }
        crate::check_blur_px(self.blur_px)?;
        if !(self.radial_coupling.is_finite() && self.radial_coupling.abs() <= 1.0) {
            return Err(crate::SimError::out_of_range(
                "radial_coupling",
                self.radial_coupling,
                "in −1..1",
            ));
        }
        if !self.pattern_angle_deg.is_finite() {
            return Err(crate::SimError::NotFinite("pattern_angle_deg"));
        }
        if self.marker_radius_mm >= 0.5 * self.pitch_mm {
            return Err(crate::SimError::Mismatch {
                a: "marker_radius_mm",
                b: "pitch_mm",
                why: format!(
                    "a radius of {} mm is not under half the {} mm pitch: markers would touch",
                    self.marker_radius_mm, self.pitch_mm
                ),
            });
        }
        if self.field_width_mm / self.pitch_mm > 200.0 {
            return Err(crate::SimError::Mismatch {
                a: "field_width_mm",
                b: "pitch_mm",
                why: "more than 200 pitches across the field".to_string(),
            });
        }
        self.validate_surface()
    }

    /// The checks of the flat field or the dome.
    fn validate_surface(&self) -> Result<(), crate::SimError> {
        match self.surface {
            Surface::Flat => {
                if !(self.field_height_mm.is_finite() && self.field_height_mm > 0.0) {
                    return Err(crate::SimError::out_of_range(
                        "field_height_mm",
                        self.field_height_mm,
                        "positive",
                    ));
                }
                if self.max_depth_mm >= self.camera_distance_mm {
                    return Err(crate::SimError::Mismatch {
                        a: "max_depth_mm",
                        b: "camera_distance_mm",
                        why: "a press would reach the camera".to_string(),
                    });
                }
                if self.field_height_mm / self.pitch_mm > 200.0 {
                    return Err(crate::SimError::Mismatch {
                        a: "field_height_mm",
                        b: "pitch_mm",
                        why: "more than 200 pitches down the field".to_string(),
                    });
                }
            }
            Surface::Dome => {
                let rd = self.dome_radius_mm;
                if !(rd.is_finite() && rd > 0.0) {
                    return Err(crate::SimError::out_of_range(
                        "dome_radius_mm",
                        rd,
                        "positive",
                    ));
                }
                let theta = (0.5 * self.field_width_mm + 0.5 * self.pitch_mm) / rd;
                if theta > 0.47 * std::f64::consts::PI {
                    return Err(crate::SimError::Mismatch {
                        a: "field_width_mm",
                        b: "dome_radius_mm",
                        why: format!(
                            "{} mm reaches beyond the dome's side ({:.1} mm across at most)",
                            self.field_width_mm,
                            2.0 * (0.47 * std::f64::consts::PI * rd - 0.5 * self.pitch_mm)
                        ),
                    });
                }
                if self.camera_distance_mm <= rd {
                    return Err(crate::SimError::Mismatch {
                        a: "camera_distance_mm",
                        b: "dome_radius_mm",
                        why: format!(
                            "{} mm is not beyond the dome's {rd} mm: the camera sits below the dome's base",
                            self.camera_distance_mm
                        ),
                    });
                }
                if self.max_depth_mm >= 0.5 * rd {
                    return Err(crate::SimError::Mismatch {
                        a: "max_depth_mm",
                        b: "dome_radius_mm",
                        why: "a press must stay under half the dome's radius".to_string(),
                    });
                }
            }
        }
        Ok(())
    }

    /// Whether the chart point `(x, y)` mm lies on the marker field.
    pub fn field_contains(&self, x_mm: f64, y_mm: f64) -> bool {
        match self.surface {
            Surface::Flat => {
                x_mm.abs() <= 0.5 * self.field_width_mm && y_mm.abs() <= 0.5 * self.field_height_mm
            }
            Surface::Dome => x_mm.hypot(y_mm) <= 0.5 * self.field_width_mm,
        }
    }

    /// Whether the chart point lies on the field of `arrangement` (a round field for dot rings).
    fn pattern_contains(&self, x_mm: f64, y_mm: f64) -> bool {
        if self.arrangement == Arrangement::DotRings {
            let r = 0.5
                * self.field_width_mm.min(match self.surface {
                    Surface::Flat => self.field_height_mm,
                    Surface::Dome => self.field_width_mm,
                });
            return x_mm.hypot(y_mm) <= r + 1e-9;
        }
        self.field_contains(x_mm, y_mm)
    }

    /// Dart throwing: at most the density of a square grid of the pitch over the field's
    /// half-width and half-height, no two dots closer than 0.8 pitch.
    fn random_dots(&self, half_w: f64, half_h: f64) -> Vec<(f64, f64)> {
        let p = self.pitch_mm;
        let mut pts = Vec::new();
        let mut rng = ChaCha8Rng::seed_from_u64(self.layout_seed ^ 0xD075);
        let target = ((2.0 * half_w) * (2.0 * half_h) / (p * p)) as usize;
        let dmin2 = (0.8 * p).powi(2);
        let mut tries = 0;
        while pts.len() < target && tries < 60 * target.max(1) {
            tries += 1;
            let q = (
                rng.random_range(-half_w..=half_w),
                rng.random_range(-half_h..=half_h),
            );
            if pts
                .iter()
                .all(|&(x, y): &(f64, f64)| (x - q.0).powi(2) + (y - q.1).powi(2) >= dmin2)
            {
                pts.push(q);
            }
        }
        pts
    }

    /// Marker centres on the skin at rest, chart millimetres, in the pattern's own order.
    pub fn rest_positions_mm(&self) -> Vec<(f64, f64)> {
        let p = self.pitch_mm;
        let (s, c) = self.pattern_angle_deg.to_radians().sin_cos();
        let rot = |(x, y): (f64, f64)| (c * x - s * y, s * x + c * y);
        let half_w = 0.5 * self.field_width_mm;
        let half_h = match self.surface {
            Surface::Flat => 0.5 * self.field_height_mm,
            Surface::Dome => half_w,
        };
        let reach = half_w.hypot(half_h) / p;
        let n = reach.ceil() as i64 + 1;
        let mut pts = Vec::new();
        match self.arrangement {
            Arrangement::Grid => {
                // Centred: an even count of columns straddles the centre.
                let ox = 0.5 * ((2.0 * half_w / p + 1e-9).floor() % 2.0);
                let oy = 0.5 * ((2.0 * half_h / p + 1e-9).floor() % 2.0);
                for j in -n..=n {
                    for i in -n..=n {
                        pts.push(((i as f64 + ox) * p, (j as f64 + oy) * p));
                    }
                }
            }
            Arrangement::Hex => {
                let h = 0.5 * 3f64.sqrt() * p;
                for j in -n..=n {
                    let shift = 0.5 * (j.rem_euclid(2) as f64);
                    for i in -n..=n {
                        pts.push(((i as f64 + shift) * p, j as f64 * h));
                    }
                }
            }
            Arrangement::DotRings => {
                pts.push((0.0, 0.0));
                let phase0 = self.pattern_angle_deg.to_radians();
                for k in 1..=n {
                    let r = k as f64 * p;
                    let m = (std::f64::consts::TAU * k as f64).round() as usize;
                    let phase = phase0 + 0.5 * (k % 2) as f64 * std::f64::consts::TAU / m as f64;
                    for q in 0..m {
                        let t = phase + q as f64 * std::f64::consts::TAU / m as f64;
                        pts.push((r * t.cos(), r * t.sin()));
                    }
                }
            }
            Arrangement::Random => pts = self.random_dots(half_w, half_h),
        }
        // Lattices are cut to the field before they are turned (a field edge along a row of
        // markers keeps the whole row).
        match self.arrangement {
            Arrangement::Grid | Arrangement::Hex => {
                let e = 1e-6 * p;
                pts.retain(|&(x, y)| self.pattern_contains(x - e * x.signum(), y - e * y.signum()));
                pts = pts.into_iter().map(rot).collect();
            }
            _ => pts.retain(|&(x, y)| self.pattern_contains(x, y)),
        }
        if self.position_jitter_mm > 0.0 && self.arrangement != Arrangement::Random {
            let mut rng = ChaCha8Rng::seed_from_u64(self.layout_seed ^ 0x7177);
            let cap = 0.25 * p;
            for q in &mut pts {
                let (a, b): (f64, f64) = (
                    rng.sample(rand_distr::StandardNormal),
                    rng.sample(rand_distr::StandardNormal),
                );
                q.0 += (a * self.position_jitter_mm).clamp(-cap, cap);
                q.1 += (b * self.position_jitter_mm).clamp(-cap, cap);
            }
        }
        pts
    }

    /// The circular view's centre and radius in pixels (the dome's rim), if there is one.
    pub fn aperture_px(&self) -> Option<((f64, f64), f64)> {
        if !self.aperture || self.surface != Surface::Dome {
            return None;
        }
        let rd = self.dome_radius_mm;
        let theta = (0.5 * self.field_width_mm + 0.5 * self.pitch_mm) / rd;
        let zc = self.camera_distance_mm - rd;
        let cam = &self.camera;
        let centre = (cam.cx_px, cam.cy_px);
        let radius = (0..72)
            .filter_map(|k| {
                let phi = f64::from(k) * std::f64::consts::TAU / 72.0;
                let p = [
                    rd * theta.sin() * phi.cos(),
                    rd * theta.sin() * phi.sin(),
                    zc + rd * theta.cos(),
                ];
                cam.px_from_mm(p)
                    .map(|(x, y)| (x - centre.0).hypot(y - centre.1))
            })
            .fold(f64::INFINITY, f64::min);
        Some((centre, radius))
    }
}

impl Default for ZooConfig {
    fn default() -> Self {
        Self::TACTIP
    }
}

/// A touch: where on the skin (chart mm, 0 at the field's centre), how deep, and how far the
/// tip drags and twists the skin.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct ZooTouch {
    /// Contact x, mm.
    pub x_mm: f64,
    /// Contact y (down the image), mm.
    pub y_mm: f64,
    /// Indentation depth, mm (0: no contact).
    pub depth_mm: f64,
    /// Sideways drag along x, mm.
    pub shear_x_mm: f64,
    /// Sideways drag along y, mm.
    pub shear_y_mm: f64,
    /// Twist of the skin under the tip, degrees.
    pub twist_deg: f64,
    /// Partial slip (Cattaneo–Mindlin): the share of the contact radius that slides, 0 (the
    /// whole contact sticks: the skin under it follows the drag) to 1 (it all slides). The
    /// centre of radius `a (1 − slip_annulus)` follows the drag; the annulus around it lags,
    /// up to half the drag at the contact's edge. See [`crate::protocol::zoo_slip`].
    #[serde(default)]
    pub slip_annulus: f64,
    /// Radius of what presses, mm, where it is not the sensor's spherical tip
    /// ([`ZooConfig::tip_radius_mm`]). A flat plate on a dome of radius `R` touches as a ball
    /// of radius `R` on a plane does (Hertz: `1/R_eff = 1/R + 1/∞`), so a plate on a TacTip is
    /// `Some(dome_radius_mm)` ([`crate::protocol::zoo_plate`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub indenter_radius_mm: Option<f64>,
}

impl ZooTouch {
    /// Radius of what presses on `cfg`'s skin, mm: the touch's own indenter, or the sensor's tip.
    pub fn indenter_mm(&self, cfg: &ZooConfig) -> f64 {
        self.indenter_radius_mm.unwrap_or(cfg.tip_radius_mm)
    }

    /// The touch part of the way there, as a video shows it being made: the depth scaled by
    /// `press`, the drag and twist by `drag` (each 0..1; 1 and 1: the touch itself).
    pub fn partway(&self, press: f64, drag: f64) -> Self {
        Self {
            depth_mm: self.depth_mm * press,
            shear_x_mm: self.shear_x_mm * drag,
            shear_y_mm: self.shear_y_mm * drag,
            twist_deg: self.twist_deg * drag,
            ..*self
        }
    }

    /// Checks the touch against the sensor: on the field, depth within the skin's limit, a drag
    /// or twist only with contact, at most two pitches of drag and 30° of twist.
    pub fn validate(&self, cfg: &ZooConfig) -> Result<(), crate::SimError> {
        let v = [
            self.x_mm,
            self.y_mm,
            self.depth_mm,
            self.shear_x_mm,
            self.shear_y_mm,
            self.twist_deg,
            self.slip_annulus,
            self.indenter_mm(cfg),
        ];
        if !v.iter().all(|x| x.is_finite()) {
            return Err(crate::SimError::NotFinite("every value of a touch"));
        }
        if !(0.0..=cfg.max_depth_mm).contains(&self.depth_mm) {
            return Err(crate::SimError::out_of_range(
                "depth_mm",
                self.depth_mm,
                format!("in the skin's 0..{} mm", cfg.max_depth_mm),
            ));
        }
        if !cfg.field_contains(self.x_mm, self.y_mm) {
            return Err(crate::SimError::OffField {
                x_mm: self.x_mm,
                y_mm: self.y_mm,
            });
        }
        let drag = self.shear_x_mm.hypot(self.shear_y_mm);
        if (drag > 0.0 || self.twist_deg != 0.0) && self.depth_mm <= 0.0 {
            return Err(crate::SimError::DragWithoutContact);
        }
        if drag > 2.0 * cfg.pitch_mm {
            return Err(crate::SimError::out_of_range(
                "drag (mm)",
                drag,
                format!("at most two marker pitches ({} mm)", 2.0 * cfg.pitch_mm),
            ));
        }
        if !(0.0..=1.0).contains(&self.slip_annulus) {
            return Err(crate::SimError::out_of_range(
                "slip_annulus",
                self.slip_annulus,
                "in 0..1",
            ));
        }
        if self.twist_deg.abs() > 30.0 {
            return Err(crate::SimError::out_of_range(
                "twist_deg",
                self.twist_deg,
                "within ±30°",
            ));
        }
        if self.indenter_mm(cfg) <= 0.0 {
            return Err(crate::SimError::out_of_range(
                "indenter radius (mm)",
                self.indenter_mm(cfg),
                "positive",
            ));
        }
        Ok(())
    }
}

/// Hertz's normal-displacement profile over a spherical contact of radius 1, at `rho = r/a`.
fn hertz_profile(rho: f64) -> f64 {
    if rho <= 1.0 {
        1.0 - 0.5 * rho * rho
    } else {
        ((2.0 - rho * rho) * (1.0 / rho).asin() + (rho * rho - 1.0).sqrt()) / std::f64::consts::PI
    }
}

/// Displacement `(du, dv, w)` in mm of the skin point at chart position `(u, v)`: along the skin
/// and along its inward normal (towards the camera).
pub fn displacement_mm(cfg: &ZooConfig, touch: &ZooTouch, u: f64, v: f64) -> [f64; 3] {
    let d = touch.depth_mm;
    if d <= 0.0 {
        return [0.0, 0.0, 0.0];
    }
    let tip = touch.indenter_mm(cfg);
    let a = (tip * d).sqrt().clamp(0.05, tip);
    let t = cfg.skin_thickness_mm;
    let (dx, dy) = (u - touch.x_mm, v - touch.y_mm);
    let r = dx.hypot(dy);
    let fade = if r > a { (-(r - a) / t).exp() } else { 1.0 };
    let w = d * hertz_profile(r / a) * fade;
    // Radial motion along the skin: κ d (r/a) inside, κ d (a/r) e^{−(r−a)/t} outside.
    let radial = cfg.radial_coupling * d * if r <= a { r / a } else { a / r * fade };
    let (ux, uy) = if r > 1e-12 {
        (dx / r, dy / r)
    } else {
        (0.0, 0.0)
    };
    // The tip's drag and twist, carried with the contact; under partial slip the annulus
    // beyond the sticking centre lags behind the drag.
    let (ts, tc) = (touch.twist_deg.to_radians() * fade).sin_cos();
    let twist = (tc * dx - ts * dy - dx, ts * dx + tc * dy - dy);
    let drag = fade * stick_share(touch.slip_annulus, r / a);
    [
        radial * ux + touch.shear_x_mm * drag + twist.0,
        radial * uy + touch.shear_y_mm * drag + twist.1,
        w,
    ]
}

/// The share of the drag the skin at `rho = r/a` follows under partial slip with `annulus`
/// (the sliding share of the contact radius): 1 in the sticking centre `rho ≤ 1 − annulus`,
/// falling linearly to `1 − annulus / 2` at the contact's edge, and that beyond it.
fn stick_share(annulus: f64, rho: f64) -> f64 {
    let c = 1.0 - annulus;
    if annulus <= 0.0 || rho <= c {
        1.0
    } else {
        1.0 - 0.5 * annulus * ((rho - c) / annulus).min(1.0)
    }
}

/// Point on the dome at chart position `(u, v)`, and its outward unit normal.
fn dome_point(cfg: &ZooConfig, u: f64, v: f64) -> ([f64; 3], [f64; 3]) {
    let rd = cfg.dome_radius_mm;
    let s = u.hypot(v);
    let theta = s / rd;
    let (cu, cv) = if s > 1e-12 {
        (u / s, v / s)
    } else {
        (0.0, 0.0)
    };
    let n = [theta.sin() * cu, theta.sin() * cv, theta.cos()];
    let zc = cfg.camera_distance_mm - rd;
    ([rd * n[0], rd * n[1], zc + rd * n[2]], n)
}

/// Camera-frame position (mm) of the skin point at chart position `(u, v)` under `touch`: moved
/// along the skin, then pushed along the direction the tip presses (the skin's inward normal at
/// the contact; the camera's axis for a flat skin).
fn camera_point(cfg: &ZooConfig, touch: &ZooTouch, u: f64, v: f64) -> [f64; 3] {
    let [du, dv, w] = displacement_mm(cfg, touch, u, v);
    let (u, v) = (u + du, v + dv);
    match cfg.surface {
        Surface::Flat => [u, v, cfg.camera_distance_mm - w],
        Surface::Dome => {
            let (p, _) = dome_point(cfg, u, v);
            let (_, n) = dome_point(cfg, touch.x_mm, touch.y_mm);
            [p[0] - w * n[0], p[1] - w * n[1], p[2] - w * n[2]]
        }
    }
}

/// Truth for one marker in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZooMarker {
    /// Marker centre on the skin at rest, chart mm.
    pub rest_mm: (f64, f64),
    /// Projected centroid column, pixels (exact centroid of the drawn polygon).
    pub x_px: f64,
    /// Projected centroid row, pixels.
    pub y_px: f64,
    /// Projected area, pixels.
    pub area_px: f64,
    /// Wholly inside the image with a pixel to spare (and the circular view with three).
    pub in_view: bool,
    /// In view, clear of every other marker by `2 px + 2 × blur`, and not squeezed to a sliver
    /// (its minor axis at least 2.5 px and 35 % of its rest value): a blob of its own.
    pub visible: bool,
}

/// Boundary points of a marker per polygon.
const MARKER_VERTICES: usize = 40;

/// The projected polygon of every marker (the pattern's order) and its truth.
pub fn markers(cfg: &ZooConfig, touch: &ZooTouch) -> Vec<(Option<ConvexPolygon>, ZooMarker)> {
    let cam = &cfg.camera;
    let aperture = cfg.aperture_px();
    // A marker whose outline keeps this far inside the aperture's edge is drawn whole: 3 px on
    // a 480-line image, scaled with the image (at least a pixel).
    let rim_margin_px = (3.0 * cam.height as f64 / 480.0).clamp(1.0, 3.0);
    let rm = cfg.marker_radius_mm;
    let mut out: Vec<(Option<ConvexPolygon>, ZooMarker)> = cfg
        .rest_positions_mm()
        .into_iter()
        .map(|(mx, my)| {
            let outline = |t: &ZooTouch| {
                let verts: Vec<(f64, f64)> = (0..MARKER_VERTICES)
                    .filter_map(|k| {
                        let a = k as f64 / MARKER_VERTICES as f64 * std::f64::consts::TAU;
                        let p = camera_point(cfg, t, mx + rm * a.cos(), my + rm * a.sin());
                        cam.px_from_mm(p)
                    })
                    .collect();
                if verts.len() == MARKER_VERTICES {
                    ConvexPolygon::new(verts)
                } else {
                    None
                }
            };
            let poly = outline(touch);
            let collapsed = squeezed(poly.as_ref(), outline(&ZooTouch::default()).as_ref());
            let (area_px, (x_px, y_px)) = poly
                .as_ref()
                .map_or((0.0, (f64::NAN, f64::NAN)), |p| ring_area_centroid(p, None));
            let in_view = poly.as_ref().is_some_and(|p| {
                let (x0, y0, x1, y1) = p.bounds();
                let in_image = x0 > 1.0
                    && y0 > 1.0
                    && x1 < cam.width as f64 - 2.0
                    && y1 < cam.height as f64 - 2.0;
                in_image
                    && aperture.is_none_or(|((cx, cy), r)| {
                        p.vertices()
                            .iter()
                            .all(|&(x, y)| (x - cx).hypot(y - cy) < r - rim_margin_px)
                    })
            });
            (
                poly,
                ZooMarker {
                    rest_mm: (mx, my),
                    x_px,
                    y_px,
                    area_px,
                    in_view,
                    visible: in_view && !collapsed,
                },
            )
        })
        .collect();
    // Markers that come within the clearance of another are not separate blobs (a binarised
    // frame's edges are sharp: one pixel of background beyond the blur keeps them apart).
    let clearance = if cfg.binarise { 1.0 } else { 2.0 } + 2.0 * cfg.blur_px;
    clear_crowded(
        &mut out,
        clearance,
        |m| (m.x_px, m.y_px),
        |m| &mut m.visible,
    );
    out
}

/// Renders one camera frame of the sensor under `touch` (depth 0: the no-contact reference),
/// with noise fixed by `seed`. Returns the frame and every marker's truth in the pattern's
/// order.
pub fn render(
    cfg: &ZooConfig,
    touch: &ZooTouch,
    seed: u64,
) -> Result<(RgbImage, Vec<ZooMarker>), crate::SimError> {
    cfg.validate()?;
    touch.validate(cfg)?;
    let ms = markers(cfg, touch);
    let cam = &cfg.camera;
    let (w, h) = (cam.width, cam.height);
    let mut cov = Canvas::filled(w, h, 0.0);
    for (poly, _) in &ms {
        if let Some(p) = poly {
            cov.fill_polygon(p, None, 1.0);
        }
    }
    cov.blur(cfg.blur_px);
    let shade = shading_map(cfg, touch);
    let aperture = cfg.aperture_px();
    let look = &cfg.look;
    let (cx, cy) = (w as f32 / 2.0, h as f32 / 2.0);
    let rmax2 = cx * cx + cy * cy;
    // LED vignetting and uneven lighting.
    let light_at = |x: usize, y: usize| {
        let (fx, fy) = (x as f32 - cx, y as f32 - cy);
        ((1.0 - look.vignetting * (fx * fx + fy * fy) / rmax2)
            * (1.0 + cfg.light_gradient[0] * fx / cx + cfg.light_gradient[1] * fy / cy))
            .max(0.0)
    };
    let mut img = frame_from_coverage_lit(&cov, look.noise_sigma, seed, |x, y| {
        if let Some(((ax, ay), ar)) = aperture {
            if (x as f64 - ax).hypot(y as f64 - ay) > ar {
                return ([0.0; 3], [0.0; 3], 1.0);
            }
        }
        let mut bg = look.background;
        if let Some(s) = shade.as_ref().and_then(|m| m.at(x, y)) {
            for (b, k) in bg.iter_mut().zip(s) {
                *b *= k;
            }
        }
        (bg, look.marker, light_at(x, y))
    });
    if cfg.binarise {
        // As a data set's adaptive binarisation does: halfway between the background and the
        // markers as lit at each pixel.
        let luma = |c: [f32; 3]| 0.2989 * c[0] + 0.5870 * c[1] + 0.1140 * c[2];
        let mid = 0.5 * (luma(look.background) + luma(look.marker));
        for (k, px) in img.as_mut_slice().chunks_exact_mut(3).enumerate() {
            let v = luma([f32::from(px[0]), f32::from(px[1]), f32::from(px[2])]);
            px.fill(if v > mid * light_at(k % w, k / w) {
                255
            } else {
                0
            });
        }
    }
    Ok((img, ms.into_iter().map(|(_, m)| m).collect()))
}

/// Per-channel background gains where a flat skin is tilted by a press (coloured side lights
/// from three directions 120° apart, as GelSight's LEDs), over the pixels the press reaches.
struct ShadingMap {
    x0: usize,
    y0: usize,
    w: usize,
    gains: Vec<[f32; 3]>,
}

impl ShadingMap {
    fn at(&self, x: usize, y: usize) -> Option<[f32; 3]> {
        if x < self.x0 || y < self.y0 || x >= self.x0 + self.w {
            return None;
        }
        self.gains
            .get((y - self.y0) * self.w + (x - self.x0))
            .copied()
    }
}

fn shading_map(cfg: &ZooConfig, touch: &ZooTouch) -> Option<ShadingMap> {
    if cfg.shading == 0.0 || cfg.surface != Surface::Flat || touch.depth_mm <= 0.0 {
        return None;
    }
    let cam = &cfg.camera;
    let a = (touch.indenter_mm(cfg) * touch.depth_mm).sqrt();
    let reach = a + 6.0 * cfg.skin_thickness_mm;
    let z = cfg.camera_distance_mm;
    // Pixel bounds of the reached square (the lens maps the square's corners outwards or
    // inwards; its edges' midpoints and corners bound it closely enough for a background).
    let mut bounds = (
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    );
    for (sx, sy) in [
        (-1.0, -1.0),
        (0.0, -1.0),
        (1.0, -1.0),
        (-1.0, 0.0),
        (1.0, 0.0),
        (-1.0, 1.0),
        (0.0, 1.0),
        (1.0, 1.0),
    ] {
        if let Some((x, y)) = cam.px_from_mm([touch.x_mm + sx * reach, touch.y_mm + sy * reach, z])
        {
            bounds = (
                bounds.0.min(x),
                bounds.1.min(y),
                bounds.2.max(x),
                bounds.3.max(y),
            );
        }
    }
    let x0 = bounds.0.floor().max(0.0) as usize;
    let y0 = bounds.1.floor().max(0.0) as usize;
    let x1 = (bounds.2.ceil().max(0.0) as usize + 1).min(cam.width);
    let y1 = (bounds.3.ceil().max(0.0) as usize + 1).min(cam.height);
    if x1 <= x0 || y1 <= y0 {
        return None;
    }
    let lights: [(f64, f64); 3] = [
        (1.0, 0.0),
        (-0.5, 0.5 * 3f64.sqrt()),
        (-0.5, -0.5 * 3f64.sqrt()),
    ];
    let e = 0.02;
    let mut gains = Vec::with_capacity((x1 - x0) * (y1 - y0));
    for y in y0..y1 {
        for x in x0..x1 {
            let p = cam.mm_from_px(x as f64, y as f64, z);
            let gx = (displacement_mm(cfg, touch, p[0] + e, p[1])[2]
                - displacement_mm(cfg, touch, p[0] - e, p[1])[2])
                / (2.0 * e);
            let gy = (displacement_mm(cfg, touch, p[0], p[1] + e)[2]
                - displacement_mm(cfg, touch, p[0], p[1] - e)[2])
                / (2.0 * e);
            gains.push(lights.map(|(lx, ly)| {
                (1.0 + f64::from(cfg.shading) * (lx * gx + ly * gy)).clamp(0.2, 2.0) as f32
            }));
        }
    }
    Some(ShadingMap {
        x0,
        y0,
        w: x1 - x0,
        gains,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_and_variants_are_valid_and_in_view() {
        for kind in ZooKind::ALL {
            for seed in 0..12 {
                let c = ZooConfig::variant(kind, seed);
                c.validate()
                    .unwrap_or_else(|e| panic!("{} {seed}: {e}", kind.name()));
                let ms = markers(&c, &ZooTouch::default());
                let visible = ms.iter().filter(|(_, m)| m.visible).count();
                // On a 128-line image the dome's foreshortened outer rings come within a pixel
                // of each other and merge, as in published sets: most pins still stand apart.
                let share = if kind == ZooKind::TactipSmall {
                    0.75
                } else {
                    0.9
                };
                assert!(
                    visible as f64 >= share * ms.len() as f64 && ms.len() >= 40,
                    "{} {seed}: {visible} of {} visible at rest",
                    kind.name(),
                    ms.len()
                );
            }
        }
    }

    #[test]
    fn tactip_preset_has_about_330_pins_20_px_apart() {
        let c = ZooConfig::TACTIP;
        let ms = markers(&c, &ZooTouch::default());
        assert!((300..=360).contains(&ms.len()), "{}", ms.len());
        // Median nearest-neighbour spacing in the image.
        let mut nn: Vec<f64> = ms
            .iter()
            .map(|(_, a)| {
                ms.iter()
                    .map(|(_, b)| (a.x_px - b.x_px).hypot(a.y_px - b.y_px))
                    .filter(|d| *d > 1e-6)
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        nn.sort_by(f64::total_cmp);
        let median = nn[nn.len() / 2];
        assert!(
            (17.0..=24.0).contains(&median),
            "median pitch {median:.1} px"
        );
    }

    #[test]
    fn the_skin_holds_far_away_and_follows_the_tip_under_it() {
        let c = ZooConfig::GELSIGHT;
        let t = ZooTouch {
            x_mm: 1.0,
            y_mm: -2.0,
            depth_mm: 1.2,
            shear_x_mm: 0.8,
            shear_y_mm: -0.3,
            twist_deg: 0.0,
            slip_annulus: 0.0,
            indenter_radius_mm: None,
        };
        let under = displacement_mm(&c, &t, 1.0, -2.0);
        assert!((under[2] - 1.2).abs() < 1e-12);
        assert!((under[0] - 0.8).abs() < 1e-12 && (under[1] + 0.3).abs() < 1e-12);
        let far = displacement_mm(&c, &t, 40.0, 30.0);
        assert!(far.iter().all(|v| v.abs() < 1e-4), "{far:?}");
        // Continuous at the contact's edge.
        let a = (c.tip_radius_mm * t.depth_mm).sqrt();
        let inside = displacement_mm(&c, &t, 1.0 + a - 1e-9, -2.0);
        let outside = displacement_mm(&c, &t, 1.0 + a + 1e-9, -2.0);
        for k in 0..3 {
            assert!(
                (inside[k] - outside[k]).abs() < 1e-6,
                "{inside:?} {outside:?}"
            );
        }
    }

    /// A touch's own indenter sets the contact radius `sqrt(R d)`: Hertz's profile reaches
    /// `d / 2` at the contact's edge, for the sensor's tip and for a plate's larger radius.
    #[test]
    fn the_indenter_sets_the_contact_radius() {
        let c = ZooConfig::TACTIP;
        for indenter in [None, Some(c.dome_radius_mm)] {
            let t = ZooTouch {
                depth_mm: 2.0,
                indenter_radius_mm: indenter,
                ..ZooTouch::default()
            };
            let a = (t.indenter_mm(&c) * t.depth_mm).sqrt();
            let edge = displacement_mm(&c, &t, a, 0.0);
            assert!((edge[2] - 1.0).abs() < 1e-12, "{indenter:?}: {edge:?}");
        }
        let bad = ZooTouch {
            depth_mm: 1.0,
            indenter_radius_mm: Some(0.0),
            ..ZooTouch::default()
        };
        assert!(bad.validate(&c).is_err());
    }

    #[test]
    fn pressed_markers_come_closer_and_grow() {
        for kind in ZooKind::ALL {
            let c = kind.preset();
            let rest = markers(&c, &ZooTouch::default());
            let t = ZooTouch {
                depth_mm: c.max_depth_mm,
                ..ZooTouch::default()
            };
            let pressed = markers(&c, &t);
            let centre = rest
                .iter()
                .enumerate()
                .min_by(|a, b| {
                    let ra = a.1 .1.rest_mm.0.hypot(a.1 .1.rest_mm.1);
                    let rb = b.1 .1.rest_mm.0.hypot(b.1 .1.rest_mm.1);
                    ra.total_cmp(&rb)
                })
                .unwrap()
                .0;
            assert!(
                pressed[centre].1.area_px > 1.02 * rest[centre].1.area_px,
                "{}: {} vs {}",
                kind.name(),
                pressed[centre].1.area_px,
                rest[centre].1.area_px
            );
        }
    }

    #[test]
    fn rendering_is_deterministic_and_binarised_frames_are_two_level() {
        let mut c = ZooConfig::TACTIP;
        c.binarise = true;
        let t = ZooTouch {
            x_mm: 3.0,
            y_mm: 2.0,
            depth_mm: 4.0,
            shear_x_mm: 1.0,
            shear_y_mm: 0.0,
            twist_deg: 5.0,
            slip_annulus: 0.0,
            indenter_radius_mm: None,
        };
        let (a, _) = render(&c, &t, 5).unwrap();
        let (b, _) = render(&c, &t, 5).unwrap();
        assert_eq!(a, b);
        assert!(a.as_slice().iter().all(|&v| v == 0 || v == 255));
        // A press on the GelSight-like gel tints the background around it (coloured lights).
        let g = ZooConfig::GELSIGHT;
        let (rest, _) = render(&g, &ZooTouch::default(), 1).unwrap();
        let press = ZooTouch {
            depth_mm: 1.5,
            ..ZooTouch::default()
        };
        let (pressed, _) = render(&g, &press, 1).unwrap();
        let (x, y) = g
            .camera
            .px_from_mm([1.2, 0.0, g.camera_distance_mm])
            .unwrap();
        let (x, y) = (x.round() as usize + 3, y.round() as usize);
        let diff: i32 = (0..3)
            .map(|k| (i32::from(pressed.get(x, y)[k]) - i32::from(rest.get(x, y)[k])).abs())
            .sum();
        assert!(diff > 20, "colour change {diff}");
    }

    #[test]
    fn bad_touches_are_errors() {
        let c = ZooConfig::GELSIGHT;
        for t in [
            ZooTouch {
                depth_mm: 2.0,
                ..ZooTouch::default()
            },
            ZooTouch {
                x_mm: 30.0,
                depth_mm: 1.0,
                ..ZooTouch::default()
            },
            ZooTouch {
                shear_x_mm: 1.0,
                ..ZooTouch::default()
            },
            ZooTouch {
                depth_mm: f64::NAN,
                ..ZooTouch::default()
            },
        ] {
            assert!(render(&c, &t, 0).is_err(), "{t:?}");
        }
    }
}

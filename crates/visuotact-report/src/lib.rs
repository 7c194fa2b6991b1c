//! Report figures as SVG or PNG, chosen by the file's extension.
//!
//! Each figure is a [`Figure`]: it draws itself on any plotters backend, so the SVG and the PNG
//! of one figure are the same drawing. Text uses DejaVu Sans embedded in the binary (licence in
//! `assets/fonts/LICENSE-DejaVu.txt`), so PNGs need no system fonts. The figures of the
//! command line live in [`figures`]; estimators compute, this crate draws.
//!
//! ## Modules and what each owns
//!
//! figures as SVG or PNG with an embedded font (`Figure`, `save`: regression plots, the contact
//! map, force records, sweep performance and surface), self-contained HTML pages (`html::Page`:
//! tables, inline SVG figures, no script or outside file) and the report page of `eval
//! --report` with the sections every report page shares (`pages`). The demo's tables and page
//! live with the demo in `visuotact-experiments`. Estimators compute; this crate draws

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

pub mod figures;
pub mod html;
pub mod pages;

/// Why a figure could not be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The file's extension is neither `.svg` nor `.png`.
    #[error("{}: plots are written as .svg or .png; give one of those extensions", .0.display())]
    Extension(PathBuf),
    /// Drawing failed (plotters' message).
    #[error("drawing {}: {why}", path.display())]
    Draw {
        /// The file being drawn.
        path: PathBuf,
        /// What went wrong.
        why: String,
    },
    /// Writing the file failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// Encoding the PNG failed.
    #[error(transparent)]
    Png(#[from] visuotact_io::frames::FrameError),
}

/// DejaVu Sans, registered once as plotters' `sans-serif`.
static FONT: &[u8] = include_bytes!("../assets/fonts/DejaVuSans.ttf");

fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The font is a fixed, known-good file; failing to parse it would be a build defect.
        if plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_err() {
            visuotact_io::stderr_line(format_args!(
                "warning: embedded DejaVu Sans did not load; plot text will be missing"
            ));
        }
    });
}

/// A drawing that can be rendered on any plotters backend.
pub trait Figure {
    /// Size in pixels (SVG user units).
    fn size(&self) -> (u32, u32);
    /// Draws the figure on `root`; errors are returned as text.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String>;
}

/// Turns any plotters error into text.
pub fn text<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// Writes `figure` to `path`: `.svg` as SVG, `.png` as PNG.
pub fn save(figure: &impl Figure, path: &Path) -> Result<(), ReportError> {
    register_font();
    let (w, h) = figure.size();
    let drawn = |r: Result<(), String>| {
        r.map_err(|why| ReportError::Draw {
            path: path.to_path_buf(),
            why,
        })
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("svg") => {
            let svg = html::svg_of(figure).map_err(|why| ReportError::Draw {
                path: path.to_path_buf(),
                why,
            })?;
            Ok(visuotact_io::session::write_atomically(path, &svg)?)
        }
        Some("png") => {
            let mut rgb = vec![0u8; w as usize * h as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
                drawn(
                    figure
                        .draw(&root)
                        .and_then(|()| root.present().map_err(text)),
                )?;
            }
            let img =
                visuotact_image::RgbImage::from_vec(w as usize, h as usize, rgb).map_err(|e| {
                    ReportError::Draw {
                        path: path.to_path_buf(),
                        why: e.to_string(),
                    }
                })?;
            // `write_png` writes through a temporary file and a rename.
            Ok(visuotact_io::frames::write_png(path, &img)?)
        }
        _ => Err(ReportError::Extension(path.to_path_buf())),
    }
}

/// Writes `figure` next to `stem` as both `stem.svg` and `stem.png`.
pub fn save_both(figure: &impl Figure, stem: &Path) -> Result<(), ReportError> {
    save(figure, &stem.with_extension("svg"))?;
    save(figure, &stem.with_extension("png"))
}

/// Smallest and largest finite values, or `None` when there are none.
pub fn finite_range(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// `(lo, hi)` widened by `fraction` of its span on each side, never empty.
pub fn padded((lo, hi): (f64, f64), fraction: f64) -> (f64, f64) {
    let pad = fraction * (hi - lo).max(1e-9 * hi.abs().max(1.0));
    (lo - pad, hi + pad)
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Square;
    impl Figure for Square {
        fn size(&self) -> (u32, u32) {
            (120, 80)
        }
        fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), String> {
            root.fill(&WHITE).map_err(text)?;
            root.draw(&Rectangle::new([(10, 10), (30, 30)], BLACK.filled()))
                .map_err(text)?;
            root.draw(&Text::new("R = 1", (50, 20), ("sans-serif", 14)))
                .map_err(text)
        }
    }

    #[test]
    fn png_and_svg_of_one_figure() {
        let dir = std::env::temp_dir().join(format!("visuotact-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        save_both(&Square, &dir.join("square")).unwrap();
        let svg = std::fs::read_to_string(dir.join("square.svg")).unwrap();
        assert!(svg.contains("R = 1"));
        let png = visuotact_io::frames::read_image(&dir.join("square.png")).unwrap();
        assert_eq!((png.width(), png.height()), (120, 80));
        // The filled square is black, the background white, and the text put dark pixels
        // to the right of the square: the embedded font rendered.
        assert_eq!(png.get(20, 20), [0, 0, 0]);
        assert_eq!(png.get(5, 5), [255, 255, 255]);
        let dark_text = (50..110)
            .flat_map(|x| (5..40).map(move |y| (x, y)))
            .filter(|&(x, y)| png.get(x, y)[0] < 128)
            .count();
        assert!(dark_text > 20, "{dark_text} dark pixels of text");
        assert!(save(&Square, &dir.join("square.jpg")).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

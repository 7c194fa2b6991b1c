//! Image and frame types shared by every visuotact crate.
//!
//! Images are plain row-major buffers with no padding: [`GrayImage`] holds one `u8` per pixel,
//! [`RgbImage`] three interleaved `u8` (R, G, B). Pixel `(x, y)` is column `x`, row `y`, and its
//! centre sits at integer coordinates, as in OpenCV and scikit-image.
//!
//! ```
//! use visuotact_image::GrayImage;
//! let img = GrayImage::from_vec(3, 2, vec![0, 1, 2, 3, 4, 5]).unwrap();
//! assert_eq!(img.get(2, 1), 5);
//! ```
//!
//! ## Modules and what each owns
//!
//! `GrayImage`, `RgbImage` (row-major, pixel centres at integers) and `Frame` (id, index,
//! timestamp); `UnknownName` and `names_from_str!`, how every crate's named choices (presets,
//! algorithms, paddings) read from text; `is_marker_column`, the feature tables' per-marker
//! column names

use thiserror::Error;

/// A name that is not one of a setting's choices: what `FromStr` gives for every named choice
/// of the visuotact crates (a preset, an algorithm, a padding), with the names it takes.
///
/// ```
/// use visuotact_image::UnknownName;
/// let e = UnknownName { what: "padding", given: "odd2".into(), expected: &["odd", "even"] };
/// assert_eq!(e.to_string(), "\"odd2\" is not a padding: expected one of odd, even");
/// ```
#[derive(Debug, Error, Clone, PartialEq, Eq)]
#[error("{given:?} is not a {what}: expected one of {}", expected.join(", "))]
pub struct UnknownName {
    /// What the setting is, in words.
    pub what: &'static str,
    /// The text given.
    pub given: String,
    /// The names it takes (each also what the type's `name()` writes).
    pub expected: &'static [&'static str],
}

/// `FromStr` for a type with `from_name(&str) -> Option<Self>` and a `NAMES` list: an unknown
/// name is an [`UnknownName`] naming `$what` and listing `NAMES`.
#[macro_export]
macro_rules! names_from_str {
    ($t:ty, $what:literal) => {
        impl ::std::str::FromStr for $t {
            type Err = $crate::UnknownName;

            fn from_str(s: &str) -> Result<Self, Self::Err> {
                <$t>::from_name(s).ok_or_else(|| $crate::UnknownName {
                    what: $what,
                    given: s.to_string(),
                    expected: <$t>::NAMES,
                })
            }
        }
    };
}

/// `FromStr` for a type with `parse(&str) -> Result<Self, E>`: `"…".parse::<T>()` reads what
/// the command line reads.
#[macro_export]
macro_rules! from_str_by_parse {
    ($t:ty, $e:ty) => {
        impl ::std::str::FromStr for $t {
            type Err = $e;

            fn from_str(s: &str) -> Result<Self, Self::Err> {
                <$t>::parse(s)
            }
        }
    };
}

/// Errors from building images out of raw buffers.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum ImageError {
    /// The buffer length does not match `width × height × channels`.
    #[error(
        "buffer of {got} bytes does not fit a {width}×{height}×{channels} image (needs {need})"
    )]
    BufferSize {
        /// Image width in pixels.
        width: usize,
        /// Image height in pixels.
        height: usize,
        /// Channels per pixel.
        channels: usize,
        /// Bytes expected.
        need: usize,
        /// Bytes given.
        got: usize,
    },
}

fn check_len(width: usize, height: usize, channels: usize, got: usize) -> Result<(), ImageError> {
    let need = width * height * channels;
    if need == got {
        Ok(())
    } else {
        Err(ImageError::BufferSize {
            width,
            height,
            channels,
            need,
            got,
        })
    }
}

/// A single-channel 8-bit image.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct GrayImage {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

impl GrayImage {
    /// A black image of the given size.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0; width * height],
        }
    }

    /// Wraps a row-major buffer; fails when its length is not `width × height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<u8>) -> Result<Self, ImageError> {
        check_len(width, height, 1, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Builds an image from a function of `(x, y)`.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> u8) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// Resizes in place (contents unspecified afterwards); used to reuse buffers in live loops.
    pub fn resize(&mut self, width: usize, height: usize) {
        self.width = width;
        self.height = height;
        self.data.resize(width * height, 0);
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The pixel at column `x`, row `y`.
    pub fn get(&self, x: usize, y: usize) -> u8 {
        self.data[y * self.width + x]
    }

    /// Sets the pixel at column `x`, row `y`.
    pub fn set(&mut self, x: usize, y: usize, v: u8) {
        self.data[y * self.width + x] = v;
    }

    /// Row `y` as a slice.
    pub fn row(&self, y: usize) -> &[u8] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// Row `y` as a mutable slice.
    pub fn row_mut(&mut self, y: usize) -> &mut [u8] {
        &mut self.data[y * self.width..(y + 1) * self.width]
    }

    /// The whole buffer, row-major.
    pub fn as_slice(&self) -> &[u8] {
        &self.data
    }

    /// The whole buffer, row-major, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [u8] {
        &mut self.data
    }

    /// Consumes the image, returning its buffer.
    pub fn into_vec(self) -> Vec<u8> {
        self.data
    }
}

/// A three-channel 8-bit image, interleaved R, G, B.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct RgbImage {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

impl RgbImage {
    /// A black image of the given size.
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0; width * height * 3],
        }
    }

    /// Wraps an interleaved RGB buffer; fails when its length is not `width × height × 3`.
    pub fn from_vec(width: usize, height: usize, data: Vec<u8>) -> Result<Self, ImageError> {
        check_len(width, height, 3, data.len())?;
        Ok(Self {
            width,
            height,
            data,
        })
    }

    /// Builds an image from a function of `(x, y)` returning `[r, g, b]`.
    pub fn from_fn(
        width: usize,
        height: usize,
        mut f: impl FnMut(usize, usize) -> [u8; 3],
    ) -> Self {
        let mut data = Vec::with_capacity(width * height * 3);
        for y in 0..height {
            for x in 0..width {
                data.extend_from_slice(&f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// An RGB image with all three channels equal to `gray`.
    pub fn from_gray(gray: &GrayImage) -> Self {
        let mut data = Vec::with_capacity(gray.data.len() * 3);
        for &v in &gray.data {
            data.extend_from_slice(&[v, v, v]);
        }
        Self {
            width: gray.width,
            height: gray.height,
            data,
        }
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The pixel at column `x`, row `y`.
    pub fn get(&self, x: usize, y: usize) -> [u8; 3] {
        let i = (y * self.width + x) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// The whole buffer, row-major, interleaved.
    pub fn as_slice(&self) -> &[u8] {
        &self.data
    }

    /// The whole buffer, mutable.
    pub fn as_mut_slice(&mut self) -> &mut [u8] {
        &mut self.data
    }

    /// Consumes the image, returning its buffer.
    pub fn into_vec(self) -> Vec<u8> {
        self.data
    }
}

/// One frame from any source: the image plus where it came from and when.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Identifier written to output tables: the file name for images, the 0-based index
    /// (as text) for video frames.
    pub id: String,
    /// 0-based position of the frame in its source.
    pub index: usize,
    /// Monotonic timestamp in seconds from the start of the source.
    pub timestamp_s: f64,
    /// The pixels.
    pub image: RgbImage,
}

/// The field-summary columns that follow the markers' columns in a feature table, in the
/// order of the vision crate's `FieldSummary::values`.
pub const FIELD_COLUMNS: [&str; 6] = [
    "field_rms_px",
    "field_max_px",
    "field_top_px",
    "field_cx_px",
    "field_cy_px",
    "field_spread_px",
];

/// The millimetre twins of [`FIELD_COLUMNS`], for a sensor with a scale.
pub const FIELD_COLUMNS_MM: [&str; 6] = [
    "field_rms_mm",
    "field_max_mm",
    "field_top_mm",
    "field_cx_mm",
    "field_cy_mm",
    "field_spread_mm",
];

/// Whether a column is one of the [`FIELD_COLUMNS`] or their millimetre twins
/// ([`FIELD_COLUMNS_MM`]).
///
/// ```
/// use visuotact_image::is_field_column;
/// assert!(is_field_column("field_rms_px") && is_field_column("field_spread_mm"));
/// assert!(!is_field_column("m017_dx_px"));
/// ```
pub fn is_field_column(c: &str) -> bool {
    FIELD_COLUMNS.contains(&c) || FIELD_COLUMNS_MM.contains(&c)
}

/// Whether a feature column is a marker's: `m`, three digits, `_` (`m017_dx_px`,
/// `m017_dx_mm`), the names feature tables give each marker's values.
///
/// ```
/// use visuotact_image::is_marker_column;
/// assert!(is_marker_column("m017_dx_px"));
/// assert!(!is_marker_column("field_rms_px") && !is_marker_column("gauge_kpa"));
/// ```
pub fn is_marker_column(c: &str) -> bool {
    let b = c.as_bytes();
    b.len() > 5 && b[0] == b'm' && b[1..4].iter().all(u8::is_ascii_digit) && b[4] == b'_'
}

/// Whether a feature column is a marker's shape change rather than its displacement: its area
/// (`m017_darea_px`, `m017_darea_mm2`) or eccentricity (`m017_decc`).
///
/// ```
/// use visuotact_image::is_marker_shape_column;
/// assert!(is_marker_shape_column("m017_darea_px") && is_marker_shape_column("m017_decc"));
/// assert!(!is_marker_shape_column("m017_dx_px") && !is_marker_shape_column("field_rms_px"));
/// ```
pub fn is_marker_shape_column(c: &str) -> bool {
    is_marker_column(c) && matches!(c.get(5..), Some("darea_px" | "darea_mm2" | "decc"))
}

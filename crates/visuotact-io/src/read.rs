//! Reading whole files with bounds: only regular files (a FIFO or a device such as `/dev/zero`
//! would block or never end; a folder is not a file), at most a size limit, and images decoded
//! under a pixel limit (a small compressed file can claim gigapixels).
//!
//! Every reader of the project's inputs (tables, sensor and model files, configurations,
//! frames) goes through here, so the same rule holds for every command.

use std::io::Read;
use std::path::Path;

/// The largest table, sensor, model or configuration file read: 2 GiB.
pub const MAX_TEXT_BYTES: u64 = 2 << 30;

/// The largest image file read: 512 MiB.
pub const MAX_IMAGE_BYTES: u64 = 512 << 20;

/// The most pixels a decoded image may have: 2^28 (16 384 × 16 384); 768 MiB as RGB.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 28;

/// The most memory decoding one image may take, bytes: 1 GiB (the decoder's buffer and the
/// RGB copy). A 16 384² 8-bit RGB frame fits; a 16 000² 16-bit RGB one (1.5 GiB before the
/// copy) does not.
pub const MAX_DECODED_BYTES: u64 = 1 << 30;

/// The bytes of `path`: refused unless it is a regular file (links followed) of at most
/// `limit` bytes.
pub fn bytes_of_file(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a folder"
        } else {
            "not a regular file (a pipe, FIFO, socket or device)"
        };
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!("{kind}: expected a file"),
        ));
    }
    let too_big = |n: u64| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{n} bytes or more, beyond the limit of {limit} bytes"),
        )
    };
    if meta.len() > limit {
        return Err(too_big(meta.len()));
    }
    let mut bytes = Vec::new();
    // A file that grows while it is read stops at the limit too.
    std::fs::File::open(path)?
        .take(limit + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_big(limit + 1));
    }
    Ok(bytes)
}

/// The text of `path` ([`bytes_of_file`] with [`MAX_TEXT_BYTES`]), which must be UTF-8. A
/// byte-order mark at its start (spreadsheet programs write one into CSV files) is not part of
/// the text: every table, sensor and model reader sees its first column's name as written.
pub fn text_of_file(path: &Path) -> std::io::Result<String> {
    let mut bytes = bytes_of_file(path, MAX_TEXT_BYTES)?;
    if bytes.starts_with(UTF8_BOM) {
        bytes.drain(..UTF8_BOM.len());
    }
    String::from_utf8(bytes).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })
}

/// The UTF-8 encoding of U+FEFF, the byte-order mark.
const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_within_the_limit_are_read() {
        let d = std::env::temp_dir().join(format!("visuotact-read-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let f = d.join("t.csv");
        std::fs::write(&f, "frame,x\n").unwrap();
        assert_eq!(text_of_file(&f).unwrap(), "frame,x\n");
        // As a spreadsheet saves it: the byte-order mark is not part of the first column's name.
        std::fs::write(&f, b"\xEF\xBB\xBFtime_s,fz_n\n0,1\n").unwrap();
        assert_eq!(text_of_file(&f).unwrap(), "time_s,fz_n\n0,1\n");
        let e = bytes_of_file(&f, 4).unwrap_err().to_string();
        assert!(e.contains("beyond the limit of 4 bytes"), "{e}");
        let e = text_of_file(&d).unwrap_err().to_string();
        assert!(e.contains("a folder"), "{e}");
        let e = text_of_file(Path::new("/dev/zero"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a regular file"), "{e}");
        std::fs::write(&f, [0xff, 0xfe]).unwrap();
        assert!(text_of_file(&f)
            .unwrap_err()
            .to_string()
            .contains("not UTF-8"));
        std::fs::remove_dir_all(&d).unwrap();
    }
}

//! A video cut short decodes the frames it has, then says how many of the frames its container
//! announces are missing (a truncated file is never taken for a short one); two images that
//! would share a frame id are refused.

use std::process::Command;

use visuotact_io::frames::FrameStream;

#[test]
fn a_video_cut_short_says_so() {
    let d = std::env::temp_dir().join(format!("visuotact-video-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let whole = d.join("whole.avi");
    let made = Command::new("ffmpeg")
        .args([
            "-v",
            "error",
            "-y",
            "-f",
            "lavfi",
            "-i",
            "testsrc=size=64x48:rate=25",
        ])
        .args(["-frames:v", "40", "-c:v", "mjpeg", "-q:v", "3"])
        .arg(&whole)
        .status()
        .expect("ffmpeg is installed by scripts/test");
    assert!(made.success());
    let all: Vec<_> = FrameStream::open(std::slice::from_ref(&whole), 25.0)
        .unwrap()
        .collect();
    assert_eq!(all.len(), 40);
    assert!(all.iter().all(Result::is_ok));
    // The same file with its second half cut off.
    let bytes = std::fs::read(&whole).unwrap();
    let cut = d.join("cut.avi");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let items: Vec<_> = FrameStream::open(std::slice::from_ref(&cut), 25.0)
        .unwrap()
        .collect();
    let ok = items.iter().filter(|r| r.is_ok()).count();
    assert!((5..40).contains(&ok), "{ok} frames decoded");
    let said: Vec<String> = items
        .iter()
        .filter_map(|r| r.as_ref().err().map(ToString::to_string))
        .collect();
    assert!(
        said.iter()
            .any(|e| e.contains("of the 40 frames the file announces")),
        "{said:?}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// Two folders holding the same file names would give two frames one id: refused, naming both.
#[test]
fn two_images_with_one_id_are_refused() {
    let d = std::env::temp_dir().join(format!("visuotact-same-id-{}", std::process::id()));
    for sub in ["a", "b"] {
        std::fs::create_dir_all(d.join(sub)).unwrap();
        std::fs::write(d.join(sub).join("0001.png"), b"").unwrap();
    }
    let e = FrameStream::open(&[d.join("a"), d.join("b")], 25.0)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        e.contains("`0001.png`") && e.contains("a/0001.png") && e.contains("b/0001.png"),
        "{e}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

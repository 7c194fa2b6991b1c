//! Labels of sequences: a CSV with a header naming `video` and `slip` columns, and optionally
//! `onset_s` (others, such as `object`, are kept for grouping). `video` is a path relative to
//! the current folder, or absolute; `slip` is 0 or 1; `onset_s`, when the column is there, is
//! the second the slip began (seconds from the sequence's start, 0 or more) or empty where it
//! is not known, and only a slipping sequence has one. Paths are compared after making them
//! absolute and removing `.` and `..`, so `videos/a.avi`, `./videos/a.avi` and
//! `/data/videos/a.avi` name one video.

use std::path::{Component, Path, PathBuf};

use super::SlipError;

/// One labelled sequence.
#[derive(Clone, Debug, PartialEq)]
pub struct Label {
    /// The video, absolute.
    pub video: PathBuf,
    /// Whether it slipped.
    pub slip: bool,
    /// When the slip began, seconds from the sequence's start (the `onset_s` column).
    pub onset_s: Option<f64>,
    /// The group column's value (e.g. the object), when one was asked for.
    pub group: Option<String>,
    /// The label's line in the file (1-based).
    pub line: usize,
}

impl Label {
    /// What the label says of its sequence's slip.
    pub fn truth(&self) -> super::SlipTruth {
        super::SlipTruth {
            slip: self.slip,
            onset_s: self.onset_s,
        }
    }
}

/// `p` absolute, without `.` or `..` (not following links).
pub fn normalised(p: &Path) -> PathBuf {
    let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let mut out = PathBuf::new();
    for c in abs.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out
}

/// Reads `path`'s labels, with the column `group` (when given) kept beside each.
pub fn read_labels(path: &Path, group: Option<&str>) -> Result<Vec<Label>, SlipError> {
    let bad = |line: usize, why: String| SlipError::Labels {
        path: path.to_path_buf(),
        line,
        why,
    };
    let text = visuotact_io::read::text_of_file(path).map_err(|e| bad(0, e.to_string()))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines
        .next()
        .ok_or_else(|| bad(1, "empty: expected a header with `video` and `slip`".into()))?;
    let cells = |l: &str| -> Vec<String> {
        l.split(',')
            .map(|c| c.trim().trim_matches('"').to_string())
            .collect()
    };
    let head = cells(header);
    let col = |name: &str| head.iter().position(|h| h == name);
    let (Some(v), Some(s)) = (col("video"), col("slip")) else {
        return Err(bad(
            1,
            format!("header {header:?}: expected columns `video` and `slip`"),
        ));
    };
    let g = match group {
        Some(name) => Some(col(name).ok_or_else(|| {
            bad(
                1,
                format!("header {header:?}: no column `{name}` to group by"),
            )
        })?),
        None => None,
    };
    let onset_col = col("onset_s");
    let mut out = Vec::new();
    for (i, l) in lines {
        let line = i + 1;
        let c = cells(l);
        if c.len() != head.len() {
            return Err(bad(
                line,
                format!("{} cells where the header has {}", c.len(), head.len()),
            ));
        }
        let slip = match c[s].as_str() {
            "0" => false,
            "1" => true,
            x => return Err(bad(line, format!("slip {x:?}: expected 0 or 1"))),
        };
        if c[v].is_empty() {
            return Err(bad(line, "empty video path".into()));
        }
        let onset_s = onset_of(onset_col.map(|k| c[k].as_str()), slip, |why| bad(line, why))?;
        let video = normalised(Path::new(&c[v]));
        if let Some(first) = out.iter().find(|l: &&Label| l.video == video) {
            return Err(bad(
                line,
                format!("{} is labelled twice (line {} too)", c[v], first.line),
            ));
        }
        out.push(Label {
            video,
            slip,
            onset_s,
            group: g.map(|g| c[g].clone()),
            line,
        });
    }
    Ok(out)
}

/// The `onset_s` cell `x` of a sequence that slipped or not (`None`: no column, or empty).
fn onset_of(
    x: Option<&str>,
    slip: bool,
    bad: impl Fn(String) -> SlipError,
) -> Result<Option<f64>, SlipError> {
    let Some(x) = x.filter(|x| !x.is_empty()) else {
        return Ok(None);
    };
    match x.parse::<f64>() {
        Ok(_) if !slip => Err(bad(format!(
            "onset_s {x}: a sequence without slip has none"
        ))),
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(Some(t)),
        _ => Err(bad(format!(
            "onset_s {x:?}: expected seconds, 0 or more, or empty"
        ))),
    }
}

/// The label of each of `videos`, in their order: a video without a label, or a labelled video
/// not among them, is an error naming it.
pub fn labels_of(
    videos: &[PathBuf],
    labels: &[Label],
    path: &Path,
) -> Result<Vec<Label>, SlipError> {
    let mut out = Vec::with_capacity(videos.len());
    for v in videos {
        let n = normalised(v);
        let l = labels
            .iter()
            .find(|l| l.video == n)
            .ok_or_else(|| SlipError::Unlabelled {
                video: v.clone(),
                labels: path.to_path_buf(),
            })?;
        out.push(l.clone());
    }
    if let Some(l) = labels
        .iter()
        .find(|l| !out.iter().any(|o| o.video == l.video))
    {
        return Err(SlipError::LabelledMissing {
            labels: path.to_path_buf(),
            line: l.line,
            video: l.video.clone(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_match_videos_by_normalised_path_and_name_what_is_missing() {
        let dir = std::env::temp_dir().join(format!("vt-labels-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("labels.csv");
        let a = dir.join("a.avi").display().to_string();
        let b = dir.join("sub/../b.avi").display().to_string();
        std::fs::write(&f, format!("video,slip,object\n{a},1,cup\n\n{b},0,pen\n")).unwrap();
        let l = read_labels(&f, Some("object")).unwrap();
        assert_eq!(l.len(), 2);
        assert_eq!((l[1].video.clone(), l[1].line), (dir.join("b.avi"), 4));
        assert_eq!(l[0].group.as_deref(), Some("cup"));
        let got = labels_of(&[dir.join("./b.avi"), dir.join("a.avi")], &l, &f).unwrap();
        assert_eq!((got[0].slip, got[1].slip), (false, true));
        let e = labels_of(&[dir.join("a.avi")], &l, &f)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("labels.csv:4") && e.contains("not among the videos"),
            "{e}"
        );
        let e = labels_of(&[dir.join("c.avi")], &l, &f)
            .unwrap_err()
            .to_string();
        assert!(e.contains("c.avi: no label"), "{e}");
        std::fs::write(&f, "video,slip\nx.avi,2\n").unwrap();
        let e = read_labels(&f, None).unwrap_err().to_string();
        assert!(
            e.contains("labels.csv:2") && e.contains("expected 0 or 1"),
            "{e}"
        );
        std::fs::write(&f, "video,slip,onset_s\nx.avi,1,2.4\ny.avi,1,\nz.avi,0,\n").unwrap();
        let l = read_labels(&f, None).unwrap();
        let onsets: Vec<Option<f64>> = l.iter().map(|l| l.onset_s).collect();
        assert_eq!(onsets, [Some(2.4), None, None]);
        for (row, why) in [
            ("z.avi,0,1.0", "without slip has none"),
            ("x.avi,1,-1", "expected seconds"),
        ] {
            std::fs::write(&f, format!("video,slip,onset_s\n{row}\n")).unwrap();
            let e = read_labels(&f, None).unwrap_err().to_string();
            assert!(e.contains("labels.csv:2") && e.contains(why), "{e}");
        }
        std::fs::write(&f, "clip,slip\nx.avi,1\n").unwrap();
        assert!(read_labels(&f, None)
            .unwrap_err()
            .to_string()
            .contains("labels.csv:1"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

//! Self-contained HTML reports: one page, its tables as HTML tables or preformatted text, its
//! figures as inline SVG (the same drawings as [`crate::save`]'s files), a little CSS in the
//! page, no script and no other file — it opens offline in any browser and prints as it shows.
//!
//! ```
//! use visuotact_report::html::Page;
//! let mut page = Page::new("eval <run 3>");
//! page.table("errors", &["target", "mean |e|"], &[vec!["x_mm".into(), "0.21".into()]]);
//! let html = page.to_html();
//! assert!(html.contains("<title>eval &lt;run 3&gt;</title>"));
//! assert!(html.contains("<td>x_mm</td><td>0.21</td>"));
//! ```

use std::fmt::Write as _;
use std::path::Path;

use plotters::prelude::*;

use crate::{register_font, text, Figure, ReportError};

/// Text with `&`, `<`, `>` and `"` escaped for HTML.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            c => out.push(c),
        }
    }
    out
}

/// A figure drawn as an SVG document (plotters' message when it cannot be).
pub(crate) fn svg_of(figure: &impl Figure) -> Result<String, String> {
    register_font();
    let (w, h) = figure.size();
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        figure.draw(&root)?;
        root.present().map_err(text)?;
    }
    Ok(svg)
}

/// An HTML page being built, section by section.
#[derive(Clone, Debug, Default)]
pub struct Page {
    title: String,
    body: String,
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1280px;margin:1.5em auto;padding:0 1em;color:#222}\
h1{font-size:1.6em}h2{font-size:1.3em;border-bottom:1px solid #ccc;margin-top:2em}h3{font-size:1.1em}\
table{border-collapse:collapse;margin:0.8em 0}th,td{border:1px solid #bbb;padding:0.25em 0.6em;text-align:right}\
th{background:#eee}td:first-child,th:first-child{text-align:left}\
pre{background:#f6f6f6;padding:0.8em;overflow-x:auto;font-size:0.85em}\
figure{margin:1em 0}figcaption{font-size:0.9em;color:#555}svg{max-width:100%;height:auto}";

impl Page {
    /// An empty page with this title (also its first heading).
    pub fn new(title: &str) -> Self {
        Self {
            title: title.to_string(),
            body: format!("<h1>{}</h1>\n", escape(title)),
        }
    }

    /// A section heading (`level` 2 or 3).
    pub fn heading(&mut self, level: u8, text: &str) {
        let l = level.clamp(2, 3);
        let _ = writeln!(self.body, "<h{l}>{}</h{l}>", escape(text));
    }

    /// A paragraph of text.
    pub fn paragraph(&mut self, text: &str) {
        let _ = writeln!(self.body, "<p>{}</p>", escape(text));
    }

    /// Text kept as it is laid out (a terminal table).
    pub fn preformatted(&mut self, text: &str) {
        let _ = writeln!(self.body, "<pre>{}</pre>", escape(text));
    }

    /// A table with a caption, a header row and rows of cells.
    pub fn table(&mut self, caption: &str, header: &[&str], rows: &[Vec<String>]) {
        let _ = write!(
            self.body,
            "<table><caption>{}</caption>\n<tr>",
            escape(caption)
        );
        for h in header {
            let _ = write!(self.body, "<th>{}</th>", escape(h));
        }
        self.body.push_str("</tr>\n");
        for row in rows {
            self.body.push_str("<tr>");
            for cell in row {
                let _ = write!(self.body, "<td>{}</td>", escape(cell));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
    }

    /// A figure drawn inline as SVG, with a caption.
    pub fn figure(&mut self, caption: &str, figure: &impl Figure) -> Result<(), ReportError> {
        let svg = svg_of(figure).map_err(|why| ReportError::Draw {
            path: caption.into(),
            why,
        })?;
        // The SVG document's own XML declaration has no place inside HTML.
        let svg = svg
            .find("<svg")
            .map_or(svg.as_str(), |i| &svg[i..])
            .to_string();
        let _ = writeln!(
            self.body,
            "<figure>{svg}<figcaption>{}</figcaption></figure>",
            escape(caption)
        );
        Ok(())
    }

    /// The page as one HTML document.
    pub fn to_html(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
             <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
             <title>{}</title><style>{STYLE}</style></head>\n<body>\n{}</body></html>\n",
            escape(&self.title),
            self.body
        )
    }

    /// Writes the page to `path` (through a temporary file and a rename).
    pub fn write(&self, path: &Path) -> Result<(), ReportError> {
        Ok(visuotact_io::session::write_atomically(
            path,
            &self.to_html(),
        )?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::figures::{Panel, RegressionPlot};

    #[test]
    fn figures_are_inline_svg_and_text_is_escaped() {
        let panels: Vec<Panel> = vec![("x_mm".into(), vec![(0.0, 0.1), (1.0, 0.9)], 0.99)];
        let mut page = Page::new("a & b");
        page.heading(2, "<figures>");
        page.figure("x against truth", &RegressionPlot(&panels))
            .unwrap();
        page.preformatted("a  <b>\n1  2");
        let html = page.to_html();
        assert!(html.starts_with("<!DOCTYPE html>"));
        assert!(html.contains("<h2>&lt;figures&gt;</h2>"));
        assert!(html.contains("<figure><svg"), "{html}");
        assert!(!html.contains("<?xml"));
        assert!(html.contains("<pre>a  &lt;b&gt;\n1  2</pre>"));
        // Nothing outside the page: no links, scripts or images by address.
        for outside in ["<script", "<link", "src=", "href=", "url("] {
            assert!(!html.contains(outside), "{outside}");
        }
    }
}

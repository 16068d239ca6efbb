//! The few SVG pieces the pattern is drawn with: numbers, text, lines, arrows. Every coordinate
//! and length is in millimetres (the documents' user unit).

use std::fmt::Write;

/// A number as SVG writes it: at most three decimals (a micrometre), no trailing zeros.
pub(super) fn num(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    match s {
        "-0" | "" => "0".into(),
        s => s.into(),
    }
}

/// A length for people: millimetres with at most two decimals ("500", "50.25").
pub(super) fn mm_text(v_mm: f64) -> String {
    let s = format!("{v_mm:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Text escaped for XML character data and attribute values.
pub(super) fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
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

/// Where a text's anchor point is, horizontally.
#[derive(Clone, Copy)]
pub(super) enum Anchor {
    Start,
    Middle,
    End,
}

impl Anchor {
    fn name(self) -> &'static str {
        match self {
            Self::Start => "start",
            Self::Middle => "middle",
            Self::End => "end",
        }
    }
}

/// Writes SVG elements into a string.
#[derive(Default)]
pub(super) struct SvgWriter {
    pub(super) out: String,
}

impl SvgWriter {
    /// A raw fragment (already valid SVG).
    pub(super) fn raw(&mut self, fragment: &str) {
        self.out.push_str(fragment);
    }

    pub(super) fn rect(&mut self, [x, y, w, h]: [f64; 4], attrs: &str) {
        let _ = writeln!(
            self.out,
            r#"<rect x="{}" y="{}" width="{}" height="{}" {attrs}/>"#,
            num(x),
            num(y),
            num(w),
            num(h)
        );
    }

    pub(super) fn circle(&mut self, [x, y]: [f64; 2], r: f64, attrs: &str) {
        let _ = writeln!(
            self.out,
            r#"<circle cx="{}" cy="{}" r="{}" {attrs}/>"#,
            num(x),
            num(y),
            num(r)
        );
    }

    pub(super) fn line(&mut self, [x0, y0]: [f64; 2], [x1, y1]: [f64; 2], width_mm: f64, attrs: &str) {
        let _ = writeln!(
            self.out,
            r#"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke-width="{}" {attrs}/>"#,
            num(x0),
            num(y0),
            num(x1),
            num(y1),
            num(width_mm)
        );
    }

    /// Text of height `size_mm` with its baseline through `at`; `rotate_deg` turns it about
    /// `at` (clockwise on the page).
    pub(super) fn text(&mut self, at: [f64; 2], size_mm: f64, anchor: Anchor, rotate_deg: f64, text: &str) {
        let transform = if rotate_deg == 0.0 {
            String::new()
        } else {
            format!(
                r#" transform="rotate({} {} {})""#,
                num(rotate_deg),
                num(at[0]),
                num(at[1])
            )
        };
        let _ = writeln!(
            self.out,
            r#"<text x="{}" y="{}" font-size="{}" text-anchor="{}"{transform}>{}</text>"#,
            num(at[0]),
            num(at[1]),
            num(size_mm),
            anchor.name(),
            escape(text)
        );
    }

    /// A filled arrowhead with its tip at `tip`, pointing along `(dx, dy)` (any length), `len`
    /// long and half as wide.
    pub(super) fn arrowhead(&mut self, tip: [f64; 2], (dx, dy): (f64, f64), len: f64, fill: &str) {
        let norm = dx.hypot(dy).max(1e-12);
        let (ux, uy) = (dx / norm, dy / norm);
        let base = [tip[0] - ux * len, tip[1] - uy * len];
        let half = len / 4.0;
        let _ = writeln!(
            self.out,
            r#"<polygon points="{},{} {},{} {},{}" fill="{fill}"/>"#,
            num(tip[0]),
            num(tip[1]),
            num(base[0] - uy * half),
            num(base[1] + ux * half),
            num(base[0] + uy * half),
            num(base[1] - ux * half)
        );
    }

    /// A registration cross (a circle and two lines) at `at`, `size_mm` across, in red over a
    /// white halo so that it shows on the black field and on white paper alike.
    pub(super) fn registration_cross(&mut self, [x, y]: [f64; 2], size_mm: f64) {
        let h = size_mm / 2.0;
        for (colour, width) in [("#ffffff", 0.8), ("#d40000", 0.25)] {
            let attrs = format!(r#"stroke="{colour}" fill="none""#);
            self.line([x - h, y], [x + h, y], width, &attrs);
            self.line([x, y - h], [x, y + h], width, &attrs);
            let _ = writeln!(
                self.out,
                r#"<circle cx="{}" cy="{}" r="{}" stroke-width="{}" {attrs}/>"#,
                num(x),
                num(y),
                num(h * 0.6),
                num(width)
            );
        }
    }
}

/// A standalone SVG document `width_mm` x `height_mm` whose user unit is the millimetre.
pub(super) fn document(width_mm: f64, height_mm: f64, description: &str, body: &str) -> String {
    format!(
        concat!(
            r#"<?xml version="1.0" encoding="UTF-8"?>"#,
            "\n",
            r#"<svg xmlns="http://www.w3.org/2000/svg" version="1.1" width="{w}mm" height="{h}mm" viewBox="0 0 {w} {h}" font-family="sans-serif">"#,
            "\n<desc>{desc}</desc>\n{body}</svg>\n"
        ),
        w = num(width_mm),
        h = num(height_mm),
        desc = escape(description),
        body = body
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_text() {
        assert_eq!(num(500.0), "500");
        assert_eq!(num(0.1234), "0.123");
        assert_eq!(num(-0.0001), "0");
        assert_eq!(num(12.5), "12.5");
        assert_eq!(mm_text(160.0), "160");
        assert_eq!(mm_text(50.254), "50.25");
        assert_eq!(escape(r#"a<b & "c">"#), "a&lt;b &amp; &quot;c&quot;&gt;");
    }
}

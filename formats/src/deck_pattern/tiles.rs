//! The pattern on pages of paper: each page shows one region of the true-scale drawing, the
//! regions overlap so that neighbours can be cut and laid on each other, and an overview
//! shows how the pages go together.
//!
//! A page is its paper size with a margin all round; the drawing shows through the area inside
//! the margin. Page (row r, column c) shows the drawing's region that starts at
//! `(c (w - o), r (h - o))`, `w x h` being the area inside the margin and `o` the overlap.
//! Assembly: cut each page along its dashed lines (left and top, the middle of the overlap)
//! and lay the cut edge on the neighbour's dotted line; the red crosses in the overlap fall on
//! each other.

use super::drawing::PatternDrawing;
use super::svg::{self, num, Anchor, SvgWriter};
use super::PatternError;

/// Paper sizes (ISO 216).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Paper {
    A4,
    A3,
}

impl Paper {
    /// Width and height in portrait (mm).
    pub fn portrait_mm(self) -> [f64; 2] {
        match self {
            Self::A4 => [210.0, 297.0],
            Self::A3 => [297.0, 420.0],
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::A4 => "A4",
            Self::A3 => "A3",
        }
    }
}

/// How the drawing is cut into pages.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TileOptions {
    pub paper: Paper,
    /// Blank margin round each page (mm): printers do not print to the edge; the page's name,
    /// its check bar and the cut marks are printed in it.
    pub margin_mm: f64,
    /// How far neighbouring pages show the same part of the drawing (mm).
    pub overlap_mm: f64,
}

/// Least margin: room for the page's name above and its check bar below.
pub const MIN_MARGIN_MM: f64 = 8.0;
/// Least overlap: room for the cut line and the registration crosses.
pub const MIN_OVERLAP_MM: f64 = 6.0;
/// A page must show at least this much beyond its overlaps (mm).
const MIN_STEP_MM: f64 = 50.0;
/// The registration crosses' size (mm).
const CROSS_MM: f64 = 6.0;

impl Default for TileOptions {
    fn default() -> Self {
        Self {
            paper: Paper::A4,
            margin_mm: 12.0,
            overlap_mm: 10.0,
        }
    }
}

/// One page: where it sits in the grid (rows and columns from 1) and the drawing's region it
/// shows.
#[derive(Debug, Clone)]
pub struct Tile {
    pub row: usize,
    pub col: usize,
    /// The drawing's region shown inside the margin: x, y, width, height (mm).
    pub region_mm: [f64; 4],
    /// The page as an SVG document at true scale.
    pub svg: String,
}

/// The pattern cut into pages.
#[derive(Debug, Clone)]
pub struct TiledPattern {
    pub rows: usize,
    pub cols: usize,
    /// The page size as printed (mm): portrait, or landscape when that needs fewer pages.
    pub page_mm: [f64; 2],
    pub landscape: bool,
    /// Row by row.
    pub tiles: Vec<Tile>,
    /// One page with the whole drawing scaled down and the pages' outlines: not to scale.
    pub overview_svg: String,
}

impl TiledPattern {
    /// Cuts the drawing into pages; a margin or overlap that leaves no room is an error.
    pub fn new(drawing: &PatternDrawing, options: &TileOptions) -> Result<Self, PatternError> {
        let (m, o) = (options.margin_mm, options.overlap_mm);
        if !(m >= MIN_MARGIN_MM) {
            return Err(PatternError::Page {
                option: "margin_mm",
                problem: format!("must be at least {MIN_MARGIN_MM} mm, got {m}"),
            });
        }
        if !(o >= MIN_OVERLAP_MM) {
            return Err(PatternError::Page {
                option: "overlap_mm",
                problem: format!("must be at least {MIN_OVERLAP_MM} mm, got {o}"),
            });
        }
        let [pw, ph] = options.paper.portrait_mm();
        if !(pw - 2.0 * m - o >= MIN_STEP_MM) {
            return Err(PatternError::Page {
                option: "margin_mm",
                problem: format!(
                    "{m} mm margins and a {o} mm overlap leave less than {MIN_STEP_MM} mm of {} paper",
                    options.paper.name()
                ),
            });
        }
        let grid = |[w, h]: [f64; 2]| {
            let (cw, ch) = (w - 2.0 * m, h - 2.0 * m);
            let count = |size: f64, inner: f64| 1 + ((size - inner).max(0.0) / (inner - o)).ceil() as usize;
            (count(drawing.width_mm, cw), count(drawing.height_mm, ch))
        };
        let (portrait, landscape) = (grid([pw, ph]), grid([ph, pw]));
        let use_landscape = landscape.0 * landscape.1 < portrait.0 * portrait.1;
        let (page, (cols, rows)) = match use_landscape {
            true => ([ph, pw], landscape),
            false => ([pw, ph], portrait),
        };
        let layout = PageLayout {
            page,
            margin: m,
            overlap: o,
            rows,
            cols,
        };
        let mut tiles = Vec::with_capacity(rows * cols);
        for row in 1..=rows {
            for col in 1..=cols {
                let region_mm = layout.region(row, col);
                let svg = layout.page_svg(drawing, row, col, options.paper);
                tiles.push(Tile {
                    row,
                    col,
                    region_mm,
                    svg,
                });
            }
        }
        Ok(Self {
            rows,
            cols,
            page_mm: page,
            landscape: use_landscape,
            tiles,
            overview_svg: layout.overview_svg(drawing, options.paper),
        })
    }
}

/// The grid of pages over the drawing.
struct PageLayout {
    page: [f64; 2],
    margin: f64,
    overlap: f64,
    rows: usize,
    cols: usize,
}

impl PageLayout {
    /// The area inside the margin (mm).
    fn inner(&self) -> [f64; 2] {
        [self.page[0] - 2.0 * self.margin, self.page[1] - 2.0 * self.margin]
    }

    /// The drawing's region page (row, col) shows (both from 1).
    fn region(&self, row: usize, col: usize) -> [f64; 4] {
        let [w, h] = self.inner();
        [
            (col - 1) as f64 * (w - self.overlap),
            (row - 1) as f64 * (h - self.overlap),
            w,
            h,
        ]
    }

    fn page_svg(&self, drawing: &PatternDrawing, row: usize, col: usize, paper: Paper) -> String {
        let [pw, ph] = self.page;
        let (m, o) = (self.margin, self.overlap);
        let [x0, y0, w, h] = self.region(row, col);
        let mut s = SvgWriter::default();
        s.rect([0.0, 0.0, pw, ph], r##"fill="#ffffff""##);
        s.raw(&format!(
            "<defs><clipPath id=\"page-content\"><rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\"/></clipPath></defs>\n",
            num(m),
            num(m),
            num(w),
            num(h)
        ));
        // The drawing moved so that its region falls inside the margin, clipped there.
        let shift = format!("translate({} {})", num(m - x0), num(m - y0));
        s.raw(&format!(
            "<g clip-path=\"url(#page-content)\"><g transform=\"{shift}\">\n"
        ));
        s.raw(&drawing.body);
        self.crosses(&mut s, [x0, y0, w, h]);
        s.raw("</g></g>\n");
        let thin = r##"stroke="#000000""##;
        // Corner marks just outside the area inside the margin.
        let mark = (0.6 * m).min(8.0);
        for (x, sx) in [(m, -1.0), (m + w, 1.0)] {
            for (y, sy) in [(m, -1.0), (m + h, 1.0)] {
                s.line([x + sx, y], [x + sx * mark, y], 0.2, thin);
                s.line([x, y + sy], [x, y + sy * mark], 0.2, thin);
            }
        }
        // Grey: seen on the black field and on white paper alike. Across the margins to the
        // paper's edge, for the scissors and the eye.
        let dashed = r##"stroke="#8c8c8c" stroke-dasharray="3 2""##;
        let dotted = r##"stroke="#8c8c8c" stroke-dasharray="0.6 1.2""##;
        let small = (0.25 * m).min(3.0);
        let name = |r: usize, c: usize| format!("r{r}c{c}");
        if col > 1 {
            let x = m + o / 2.0;
            s.line([x, 0.0], [x, ph], 0.3, dashed);
        }
        if row > 1 {
            let y = m + o / 2.0;
            s.line([0.0, y], [pw, y], 0.3, dashed);
        }
        if col < self.cols {
            let x = m + w - o / 2.0;
            s.line([x, m], [x, m + h], 0.3, dotted);
            s.text(
                [m + w + 0.6 * m, m + h / 2.0],
                small,
                Anchor::Middle,
                90.0,
                &format!("lay {}'s cut edge on the dotted line", name(row, col + 1)),
            );
        }
        if row < self.rows {
            let y = m + h - o / 2.0;
            s.line([m, y], [m + w, y], 0.3, dotted);
        }
        // The page's name above, a check bar below.
        let label = (0.3 * m).min(3.0);
        s.text(
            [m + o, 0.6 * m],
            label,
            Anchor::Start,
            0.0,
            &format!(
                "deckwatch deck pattern {} (row {row} of {}, column {col} of {}), {} {}; print at 100 %; cut on dashed lines",
                name(row, col),
                self.rows,
                self.cols,
                paper.name(),
                if pw > ph { "landscape" } else { "portrait" },
            ),
        );
        let bar_y = m + h + 0.3 * m;
        s.line([m, bar_y], [m + 100.0, bar_y], 0.25, thin);
        for k in 0..=10 {
            let x = m + 10.0 * k as f64;
            let len = if k % 5 == 0 { 2.0 } else { 1.2 };
            s.line([x, bar_y], [x, bar_y + len], 0.25, thin);
        }
        s.text(
            [m + 102.0, bar_y + 0.35 * small],
            small,
            Anchor::Start,
            0.0,
            &format!("100 mm: measure after printing ({})", name(row, col)),
        );
        svg::document(
            pw,
            ph,
            &format!(
                "{}; page {} of {} x {}",
                drawing.description(),
                name(row, col),
                self.rows,
                self.cols
            ),
            &s.out,
        )
    }

    /// Registration crosses in this page's overlaps with its neighbours, at positions in the
    /// drawing that both pages compute alike: a quarter of the overlap inside the part a cut
    /// page keeps, in the middle of each page along the seam.
    fn crosses(&self, s: &mut SvgWriter, [x0, y0, w, h]: [f64; 4]) {
        let o = self.overlap;
        let [iw, ih] = self.inner();
        // Vertical seams (between columns c - 1 and c) and horizontal ones (rows r - 1, r).
        for c in 2..=self.cols {
            let x = (c - 1) as f64 * (iw - o) + 0.75 * o;
            for r in 1..=self.rows {
                let y = (r - 1) as f64 * (ih - o) + 0.5 * ih;
                if x >= x0 && x <= x0 + w && y >= y0 && y <= y0 + h {
                    s.registration_cross([x, y], CROSS_MM.min(o));
                }
            }
        }
        for r in 2..=self.rows {
            let y = (r - 1) as f64 * (ih - o) + 0.75 * o;
            for c in 1..=self.cols {
                let x = (c - 1) as f64 * (iw - o) + 0.5 * iw;
                if x >= x0 && x <= x0 + w && y >= y0 && y <= y0 + h {
                    s.registration_cross([x, y], CROSS_MM.min(o));
                }
            }
        }
    }

    /// The whole drawing scaled into one page, with each page's region outlined and named.
    fn overview_svg(&self, drawing: &PatternDrawing, paper: Paper) -> String {
        let m = self.margin;
        let header = 12.0;
        let fit = |[pw, ph]: [f64; 2]| {
            ((pw - 2.0 * m) / drawing.width_mm).min((ph - 2.0 * m - header) / drawing.height_mm)
        };
        // The overview's own orientation: whichever shows the drawing larger.
        let [short, long] = paper.portrait_mm();
        let [pw, ph] = match fit([long, short]) > fit([short, long]) {
            true => [long, short],
            false => [short, long],
        };
        let scale = fit([pw, ph]);
        let mut s = SvgWriter::default();
        s.rect([0.0, 0.0, pw, ph], r##"fill="#ffffff""##);
        s.text(
            [m, m + 4.0],
            4.0,
            Anchor::Start,
            0.0,
            &format!(
                "deckwatch deck pattern: overview of {} x {} {} pages (rows x columns), NOT to scale",
                self.rows,
                self.cols,
                paper.name()
            ),
        );
        s.text(
            [m, m + 9.0],
            3.0,
            Anchor::Start,
            0.0,
            &format!(
                "the drawing is {} x {} mm; pages overlap by {} mm: cut on the dashed lines, lay the cut edge on the dotted line",
                num(drawing.width_mm),
                num(drawing.height_mm),
                num(self.overlap)
            ),
        );
        s.raw(&format!(
            "<g transform=\"translate({} {}) scale({})\">\n",
            num(m),
            num(m + header),
            scale
        ));
        s.raw(&drawing.body);
        let outline = format!(
            r##"fill="none" stroke="#0050d0" stroke-width="{}""##,
            scale.recip() * 0.3
        );
        for row in 1..=self.rows {
            for col in 1..=self.cols {
                let [x, y, w, h] = self.region(row, col);
                s.rect([x, y, w, h], &outline);
                // In the region's corner beyond the overlaps, 2.5 mm high on the overview.
                let size = 2.5 / scale;
                s.raw(&format!(
                    "<text x=\"{}\" y=\"{}\" font-size=\"{}\" fill=\"#0050d0\">r{row}c{col}</text>\n",
                    num(x + self.overlap + 0.3 * size),
                    num(y + self.overlap + 1.1 * size),
                    num(size),
                ));
            }
        }
        s.raw("</g>\n");
        svg::document(
            pw,
            ph,
            &format!("{}; overview, not to scale", drawing.description()),
            &s.out,
        )
    }
}

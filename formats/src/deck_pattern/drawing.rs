//! The whole pattern on one sheet at true scale: the discs on a black field, the marker labels,
//! the bow's arrow, the dimension lines, the 100 mm check bar and the title.
//!
//! Everything but the discs lies outside the black field: the detector sees white discs on a
//! dark ground, and a line or a letter near a disc would spoil its measurement (its region's
//! background plane, its coverage), in the photograph `deckwatch pattern check` measures as on
//! the deck.

use super::svg::{self, mm_text, Anchor, SvgWriter};
use super::PatternError;
use deckwatch_common::deck::BOW;
use deckwatch_common::DeckLayout;

/// The text height per millimetre of the field's half side, and its bounds: legible on a
/// printed page, not dominating a deck metres across.
const TEXT_PER_FIELD_MM: f64 = 1.0 / 40.0;
const MIN_TEXT_MM: f64 = 3.0;
const MAX_TEXT_MM: f64 = 40.0;
/// The check bar's length.
pub const CHECK_BAR_MM: f64 = 100.0;
/// The check bar's sentence.
pub const CHECK_BAR_TEXT: &str = "100 mm: measure after printing";

const BLACK: &str = "#000000";

/// The pattern of one deck layout as a drawing in millimetres: origin at the sheet's top-left
/// corner, x to the right, y down. The deck is seen from above with its +x (the bow) to the
/// right and +y (port) up, so the ring runs counter-clockwise on the sheet as on the deck
/// (CONVENTIONS.md §4).
#[derive(Debug, Clone)]
pub struct PatternDrawing {
    /// The layout drawn.
    pub layout: DeckLayout,
    /// The sheet's size (mm).
    pub width_mm: f64,
    pub height_mm: f64,
    /// Where the deck's centre is on the sheet (mm).
    pub centre_mm: [f64; 2],
    /// Half the side of the black square field the discs lie on (mm).
    pub field_half_mm: f64,
    /// The ends of the check bar's line (mm).
    pub check_bar_mm: [[f64; 2]; 2],
    /// The text height (mm).
    pub(super) text_mm: f64,
    /// The drawing's elements, without the enclosing document.
    pub(super) body: String,
}

impl PatternDrawing {
    /// Draws the layout's pattern; an invalid layout is an error.
    pub fn new(layout: &DeckLayout) -> Result<Self, PatternError> {
        layout.validate().map_err(PatternError::Layout)?;
        let ring = 1e3 * layout.ring_radius_m;
        let disc = 1e3 * layout.marker_radius_m;
        let bow = 1e3 * layout.bow_marker_radius_m;
        // A margin of the largest disc's diameter around the ring: the detector measures a
        // disc against the ground around it.
        let field = ring + 2.0 * disc.max(bow);
        let t = (field * TEXT_PER_FIELD_MM).clamp(MIN_TEXT_MM, MAX_TEXT_MM);
        // Bands around the field, in text heights: labels (2.6) everywhere; the title above;
        // the bow's arrow right; the dimensions and the check bar below.
        let (left, top, right, bottom) = (3.0 * t, 8.0 * t, 8.0 * t, 13.5 * t);
        let width_mm = (left + 2.0 * field + right).max(left + CHECK_BAR_MM + 18.0 * t);
        let height_mm = top + 2.0 * field + bottom;
        let centre = [left + field, top + field];
        let field_bottom = centre[1] + field;
        let bar_y = field_bottom + 11.1 * t;
        let bar_x = centre[0] - field;
        let mut drawing = Self {
            layout: *layout,
            width_mm,
            height_mm,
            centre_mm: centre,
            field_half_mm: field,
            check_bar_mm: [[bar_x, bar_y], [bar_x + CHECK_BAR_MM, bar_y]],
            text_mm: t,
            body: String::new(),
        };
        let mut w = SvgWriter::default();
        w.rect([0.0, 0.0, width_mm, height_mm], r##"fill="#ffffff""##);
        w.rect(
            [centre[0] - field, centre[1] - field, 2.0 * field, 2.0 * field],
            r##"id="field" fill="#000000""##,
        );
        for i in 0..layout.marker_count() {
            let p = layout.marker_position(i);
            w.circle(
                drawing.deck_to_sheet_mm([p.x, p.y]),
                1e3 * layout.disc_radius(i),
                &format!(r##"id="marker-{i}" fill="#ffffff""##),
            );
        }
        drawing.labels(&mut w);
        drawing.bow_arrow(&mut w);
        drawing.dimensions(&mut w, ring, disc, bow);
        drawing.check_bar(&mut w);
        drawing.title(&mut w, ring, disc, bow);
        drawing.body = w.out;
        Ok(drawing)
    }

    /// Where a point of the deck plane (metres, deck frame) lies on the sheet (mm).
    pub fn deck_to_sheet_mm(&self, [x_m, y_m]: [f64; 2]) -> [f64; 2] {
        [self.centre_mm[0] + 1e3 * x_m, self.centre_mm[1] - 1e3 * y_m]
    }

    /// The black field as (x, y, width, height) on the sheet (mm).
    pub fn field_mm(&self) -> [f64; 4] {
        let f = self.field_half_mm;
        [self.centre_mm[0] - f, self.centre_mm[1] - f, 2.0 * f, 2.0 * f]
    }

    /// What the drawing is, for the documents' `<desc>`.
    pub(super) fn description(&self) -> String {
        let l = &self.layout;
        format!(
            "deckwatch deck pattern: ring_radius_m={} marker_radius_m={} bow_marker_radius_m={} n_ring={}; \
             1 user unit = 1 mm; seen from above, deck +x (bow) to the right, +y (port) up",
            l.ring_radius_m, l.marker_radius_m, l.bow_marker_radius_m, l.n_ring
        )
    }

    /// The drawing as a standalone SVG document at true scale (width and height in mm, the
    /// view box in mm).
    pub fn svg(&self) -> String {
        svg::document(self.width_mm, self.height_mm, &self.description(), &self.body)
    }

    /// The ring markers' numbers outside the field, each on the ray from the centre through
    /// its marker (the centre, 0, is named in the title): outside, because the detector
    /// must see nothing but discs on the field.
    fn labels(&self, w: &mut SvgWriter) {
        let t = self.text_mm;
        for i in 1..=self.layout.n_ring {
            let angle = 2.0 * std::f64::consts::PI * (i - 1) as f64 / self.layout.n_ring as f64;
            let (dx, dy) = (angle.cos(), -angle.sin());
            // To the square's edge along the ray, then a band's width beyond it.
            let reach = (self.field_half_mm + 1.3 * t) / dx.abs().max(dy.abs());
            let at = [
                self.centre_mm[0] + reach * dx,
                self.centre_mm[1] + reach * dy + 0.35 * t,
            ];
            w.text(at, t, Anchor::Middle, 0.0, &i.to_string());
        }
    }

    /// An arrow from the centre's side toward the bow marker, right of the field on the line
    /// through the centre and marker 1.
    fn bow_arrow(&self, w: &mut SvgWriter) {
        let t = self.text_mm;
        let y = self.centre_mm[1];
        let x0 = self.centre_mm[0] + self.field_half_mm + 2.8 * t;
        let x1 = x0 + 4.0 * t;
        w.line(
            [x0, y],
            [x1 - 0.5 * t, y],
            t / 6.0,
            &format!(r#"stroke="{BLACK}""#),
        );
        w.arrowhead([x1, y], (1.0, 0.0), t, BLACK);
        w.text([0.5 * (x0 + x1), y - 0.5 * t], t, Anchor::Middle, 0.0, "BOW");
        w.text(
            [0.5 * (x0 + x1), y + 1.3 * t],
            0.7 * t,
            Anchor::Middle,
            0.0,
            "marker 1, +x",
        );
    }

    /// The three dimension rows below the field: the centre disc's diameter, the bow disc's,
    /// and the ring's radius (centre to a ring marker's centre), each with its value.
    fn dimensions(&self, w: &mut SvgWriter, ring: f64, disc: f64, bow: f64) {
        let t = self.text_mm;
        let [cx, _] = self.centre_mm;
        let field_bottom = self.centre_mm[1] + self.field_half_mm;
        // Extension lines start below the labels' band.
        let from = field_bottom + 2.4 * t;
        let row = |k: f64| field_bottom + (3.6 + 2.5 * k) * t;
        let size = 0.8 * t;
        let y = row(0.0);
        self.dimension(w, [cx - disc, cx + disc], y, from);
        w.text(
            [cx + disc + 0.6 * t, y + 0.35 * size],
            size,
            Anchor::Start,
            0.0,
            &format!("Ø {} mm", mm_text(2.0 * disc)),
        );
        let y = row(1.0);
        self.dimension(w, [cx + ring - bow, cx + ring + bow], y, from);
        w.text(
            [cx + ring - bow - 0.6 * t, y + 0.35 * size],
            size,
            Anchor::End,
            0.0,
            &format!("bow Ø {} mm", mm_text(2.0 * bow)),
        );
        let y = row(2.0);
        self.dimension(w, [cx, cx + ring], y, from);
        w.text(
            [cx + 0.5 * ring, y - 0.4 * t],
            size,
            Anchor::Middle,
            0.0,
            &format!("ring radius {} mm", mm_text(ring)),
        );
    }

    /// One horizontal dimension: extension lines down from `from`, the dimension line at `y`
    /// between `x0` and `x1`, arrowheads on it pointing at the extension lines.
    fn dimension(&self, w: &mut SvgWriter, [x0, x1]: [f64; 2], y: f64, from: f64) {
        let t = self.text_mm;
        let stroke = (t / 12.0).max(0.2);
        let attrs = format!(r#"stroke="{BLACK}""#);
        for x in [x0, x1] {
            w.line([x, from], [x, y + 0.4 * t], stroke, &attrs);
        }
        w.line([x0, y], [x1, y], stroke, &attrs);
        let arrow = (0.5 * t).min((x1 - x0) / 3.0);
        w.arrowhead([x0, y], (-1.0, 0.0), arrow, BLACK);
        w.arrowhead([x1, y], (1.0, 0.0), arrow, BLACK);
    }

    /// The 100 mm bar with a tick every 10 mm: what a ruler checks after printing (a scaled
    /// print scales the bar with everything else, so only a ruler tells).
    fn check_bar(&self, w: &mut SvgWriter) {
        let t = self.text_mm;
        let [[x0, y], [x1, _]] = self.check_bar_mm;
        let stroke = (t / 12.0).clamp(0.2, 0.4);
        let attrs = format!(r#"stroke="{BLACK}""#);
        w.line([x0, y], [x1, y], stroke, &attrs);
        for k in 0..=10 {
            let x = x0 + 10.0 * k as f64;
            let long = k % 5 == 0;
            let len = if long { 0.7 * t } else { 0.4 * t };
            w.line([x, y], [x, y - len], stroke, &attrs);
            if long {
                w.text(
                    [x, y - 0.9 * t],
                    0.6 * t,
                    Anchor::Middle,
                    0.0,
                    &(10 * k).to_string(),
                );
            }
        }
        w.text([x0, y + 1.2 * t], 0.8 * t, Anchor::Start, 0.0, CHECK_BAR_TEXT);
    }

    /// The title: what the sheet is and the layout's values.
    fn title(&self, w: &mut SvgWriter, ring: f64, disc: f64, bow: f64) {
        let t = self.text_mm;
        let n = self.layout.n_ring;
        w.text(
            [t, 2.3 * t],
            1.3 * t,
            Anchor::Start,
            0.0,
            "deckwatch deck pattern: true scale 1:1, print at 100 % (no fit to page)",
        );
        w.text(
            [t, 3.8 * t],
            0.8 * t,
            Anchor::Start,
            0.0,
            &format!(
                "ring radius {} mm, {n} ring markers, disc Ø {} mm, bow disc Ø {} mm",
                mm_text(ring),
                mm_text(2.0 * disc),
                mm_text(2.0 * bow)
            ),
        );
        w.text(
            [t, 5.0 * t],
            0.8 * t,
            Anchor::Start,
            0.0,
            &format!(
                "seen from above: bow (+x, marker {BOW}) right, port (+y) up; markers: 0 centre, \
                 1 bow, 2-{n} ring, counter-clockwise"
            ),
        );
    }
}

//! The SVG read back with an XML parser nobody here wrote (quick-xml): well formed, in
//! millimetres, the discs where the layout puts them, the values printed, the pages covering
//! the sheet.

use super::*;
use quick_xml::events::{BytesStart, Event};

/// One element of a parsed document: its name, attributes and the text directly inside it.
#[derive(Debug, Clone)]
struct Element {
    name: String,
    attrs: Vec<(String, String)>,
    text: String,
}

impl Element {
    fn attr(&self, key: &str) -> Option<&str> {
        self.attrs.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    fn number(&self, key: &str) -> f64 {
        self.attr(key)
            .unwrap_or_else(|| panic!("{} has no {key}", self.name))
            .parse()
            .unwrap()
    }
}

/// Parses a whole document; panics on anything that is not well-formed XML with one root.
fn parse(svg: &str) -> Vec<Element> {
    let mut reader = quick_xml::Reader::from_str(svg);
    let (mut out, mut open, mut roots) = (Vec::new(), Vec::<usize>::new(), 0);
    let element = |e: &BytesStart<'_>| Element {
        name: String::from_utf8(e.name().as_ref().to_vec()).unwrap(),
        attrs: e
            .attributes()
            .map(|a| {
                let a = a.expect("a well-formed attribute");
                (
                    String::from_utf8(a.key.as_ref().to_vec()).unwrap(),
                    String::from_utf8(a.value.to_vec()).unwrap(),
                )
            })
            .collect(),
        text: String::new(),
    };
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Start(e) => {
                roots += usize::from(open.is_empty());
                open.push(out.len());
                out.push(element(&e));
            }
            Event::Empty(e) => {
                roots += usize::from(open.is_empty());
                out.push(element(&e));
            }
            Event::End(_) => {
                open.pop().expect("an end tag closes an open element");
            }
            Event::Text(t) => {
                if let Some(&i) = open.last() {
                    out[i].text.push_str(&t.decode().unwrap());
                }
            }
            Event::GeneralRef(r) => {
                if let Some(&i) = open.last() {
                    out[i]
                        .text
                        .push_str(&format!("&{};", String::from_utf8_lossy(&r)));
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert!(open.is_empty(), "unclosed elements");
    assert_eq!(roots, 1, "one root element");
    out
}

fn texts(elements: &[Element]) -> Vec<&str> {
    elements
        .iter()
        .filter(|e| e.name == "text")
        .map(|e| e.text.as_str())
        .collect()
}

/// A deck a few metres across (a ship's), the paper's, and a small one.
fn layouts() -> [DeckLayout; 3] {
    let ship = DeckLayout {
        ring_radius_m: 2.0,
        marker_radius_m: 0.2,
        bow_marker_radius_m: 0.3,
        n_ring: 8,
    };
    let small = DeckLayout {
        ring_radius_m: 0.1,
        marker_radius_m: 0.01,
        bow_marker_radius_m: 0.016,
        n_ring: 6,
    };
    [ship, DeckLayout::paper(), small]
}

#[test]
fn the_sheet_is_well_formed_svg_in_millimetres_with_the_discs_at_true_scale() {
    for layout in layouts() {
        let drawing = PatternDrawing::new(&layout).unwrap();
        let doc = parse(&drawing.svg());
        let root = &doc[0];
        assert_eq!(root.name, "svg");
        let (w, h) = (drawing.width_mm, drawing.height_mm);
        assert_eq!(root.attr("width").unwrap(), format!("{}mm", svg::num(w)));
        assert_eq!(root.attr("height").unwrap(), format!("{}mm", svg::num(h)));
        assert_eq!(
            root.attr("viewBox").unwrap(),
            format!("0 0 {} {}", svg::num(w), svg::num(h))
        );
        let discs: Vec<&Element> = doc
            .iter()
            .filter(|e| e.attr("id").is_some_and(|id| id.starts_with("marker-")))
            .collect();
        assert_eq!(discs.len(), layout.marker_count());
        for (i, disc) in discs.iter().enumerate() {
            assert_eq!(disc.attr("id").unwrap(), format!("marker-{i}"));
            let p = layout.marker_position(i);
            let [x, y] = drawing.deck_to_sheet_mm([p.x, p.y]);
            assert!((disc.number("cx") - x).abs() < 1e-3 && (disc.number("cy") - y).abs() < 1e-3);
            assert!((disc.number("r") - 1e3 * layout.disc_radius(i)).abs() < 1e-3);
            // Inside the field with at least a disc's width of black around it.
            let [fx, fy, fw, _] = drawing.field_mm();
            let r = disc.number("r");
            assert!(x - r > fx && x + r < fx + fw && y - r > fy, "{i}");
        }
        // The sheet holds the field.
        let [fx, fy, fw, fh] = drawing.field_mm();
        assert!(fx > 0.0 && fy > 0.0 && fx + fw < w && fy + fh < h);
    }
}

#[test]
fn the_bow_is_to_the_right_and_the_ring_runs_counter_clockwise() {
    let layout = DeckLayout::paper();
    let drawing = PatternDrawing::new(&layout).unwrap();
    let [cx, cy] = drawing.centre_mm;
    let at = |i: usize| {
        let p = layout.marker_position(i);
        drawing.deck_to_sheet_mm([p.x, p.y])
    };
    assert_eq!(at(1), [cx + 500.0, cy], "bow (+x) to the right");
    let [x3, y3] = at(3);
    assert!((x3 - cx).abs() < 1e-9 && y3 < cy, "marker 3 (+y, port) up");
    let [x2, y2] = at(2);
    assert!(x2 > cx && y2 < cy, "marker 2 between them: counter-clockwise");
}

#[test]
fn the_values_labels_and_bow_are_printed() {
    let drawing = PatternDrawing::new(&DeckLayout::paper()).unwrap();
    let doc = parse(&drawing.svg());
    let all = texts(&doc);
    for wanted in [
        "ring radius 500 mm",
        "Ø 100 mm",
        "bow Ø 160 mm",
        CHECK_BAR_TEXT,
        "BOW",
        "ring radius 500 mm, 8 ring markers, disc Ø 100 mm, bow disc Ø 160 mm",
    ] {
        assert!(all.contains(&wanted), "{wanted:?} not in {all:?}");
    }
    for i in 1..=8 {
        assert!(all.contains(&i.to_string().as_str()), "label {i}");
    }
    // The ring radius's dimension line spans the centre to the bow marker's centre.
    let [cx, _] = drawing.centre_mm;
    let spans_ring = doc.iter().any(|e| {
        e.name == "line"
            && (e.number("x1") - cx).abs() < 1e-3
            && (e.number("x2") - (cx + 500.0)).abs() < 1e-3
            && e.number("y1") == e.number("y2")
    });
    assert!(spans_ring);
}

#[test]
fn the_check_bar_is_100_mm_with_a_tick_every_10_mm() {
    for layout in layouts() {
        let drawing = PatternDrawing::new(&layout).unwrap();
        let doc = parse(&drawing.svg());
        let [[x0, y], [x1, _]] = drawing.check_bar_mm;
        assert_eq!(x1 - x0, CHECK_BAR_MM);
        let ticks: Vec<f64> = doc
            .iter()
            .filter(|e| {
                e.name == "line" && (e.number("y1") - y).abs() < 1e-3 && e.number("x1") == e.number("x2")
            })
            .map(|e| e.number("x1") - x0)
            .collect();
        let expected: Vec<f64> = (0..=10).map(|k| 10.0 * k as f64).collect();
        assert_eq!(ticks.len(), 11);
        for (t, e) in ticks.iter().zip(&expected) {
            assert!((t - e).abs() < 1e-3, "{ticks:?}");
        }
        assert!(x1 < drawing.width_mm);
    }
}

#[test]
fn pages_cover_the_sheet_with_their_overlap() {
    for layout in layouts() {
        let drawing = PatternDrawing::new(&layout).unwrap();
        for paper in [Paper::A4, Paper::A3] {
            for (margin_mm, overlap_mm) in [(12.0, 10.0), (8.0, 6.0), (20.0, 25.0)] {
                let options = TileOptions {
                    paper,
                    margin_mm,
                    overlap_mm,
                };
                let tiled = TiledPattern::new(&drawing, &options).unwrap();
                assert_eq!(tiled.tiles.len(), tiled.rows * tiled.cols);
                let [pw, ph] = tiled.page_mm;
                let portrait = paper.portrait_mm();
                assert!([pw, ph] == portrait || [ph, pw] == portrait);
                // Along each axis: the first region starts at 0, each next one starts where
                // the one before ends less the overlap, the last reaches past the sheet.
                let column = |c: usize| tiled.tiles[c - 1].region_mm;
                let row = |r: usize| tiled.tiles[(r - 1) * tiled.cols].region_mm;
                assert_eq!((column(1)[0], row(1)[1]), (0.0, 0.0));
                for c in 2..=tiled.cols {
                    let (a, b) = (column(c - 1), column(c));
                    assert!((a[0] + a[2] - overlap_mm - b[0]).abs() < 1e-9);
                }
                for r in 2..=tiled.rows {
                    let (a, b) = (row(r - 1), row(r));
                    assert!((a[1] + a[3] - overlap_mm - b[1]).abs() < 1e-9);
                }
                let last = tiled.tiles.last().unwrap().region_mm;
                assert!(last[0] + last[2] >= drawing.width_mm && last[1] + last[3] >= drawing.height_mm);
                // And no page more than needed.
                assert!(column(tiled.cols)[0] < drawing.width_mm - overlap_mm || tiled.cols == 1);
                assert!(row(tiled.rows)[1] < drawing.height_mm - overlap_mm || tiled.rows == 1);
                for tile in &tiled.tiles {
                    assert_eq!(
                        (tile.region_mm[2], tile.region_mm[3]),
                        (pw - 2.0 * margin_mm, ph - 2.0 * margin_mm)
                    );
                }
            }
        }
    }
}

#[test]
fn each_page_shows_its_region_at_true_scale_and_says_which_it_is() {
    let drawing = PatternDrawing::new(&DeckLayout::paper()).unwrap();
    let tiled = TiledPattern::new(&drawing, &TileOptions::default()).unwrap();
    assert!(
        tiled.rows * tiled.cols > 4,
        "the paper's deck needs several A4 pages"
    );
    for tile in &tiled.tiles {
        let doc = parse(&tile.svg);
        let [pw, ph] = tiled.page_mm;
        assert_eq!(doc[0].attr("width").unwrap(), format!("{}mm", svg::num(pw)));
        assert_eq!(doc[0].attr("height").unwrap(), format!("{}mm", svg::num(ph)));
        // The drawing moved, not scaled: its discs keep their radii.
        let m = TileOptions::default().margin_mm;
        let shift = format!(
            "translate({} {})",
            svg::num(m - tile.region_mm[0]),
            svg::num(m - tile.region_mm[1])
        );
        assert!(doc
            .iter()
            .any(|e| e.name == "g" && e.attr("transform") == Some(shift.as_str())));
        assert!(!tile.svg.contains("scale("));
        let bow = doc.iter().find(|e| e.attr("id") == Some("marker-1")).unwrap();
        assert_eq!(bow.number("r"), 80.0);
        let name = format!(
            "deckwatch deck pattern r{}c{} (row {} of {}",
            tile.row, tile.col, tile.row, tiled.rows
        );
        assert!(texts(&doc).iter().any(|t| t.starts_with(&name)), "{name}");
    }
    let overview = parse(&tiled.overview_svg);
    let names: Vec<&str> = texts(&overview);
    for tile in &tiled.tiles {
        assert!(names.contains(&format!("r{}c{}", tile.row, tile.col).as_str()));
    }
}

/// The registration crosses of a seam are drawn by both pages at the same place of the drawing.
#[test]
fn the_crosses_of_a_seam_coincide_on_both_pages() {
    let drawing = PatternDrawing::new(&DeckLayout::paper()).unwrap();
    let options = TileOptions::default();
    let tiled = TiledPattern::new(&drawing, &options).unwrap();
    // Cross centres in the drawing's coordinates (red circles, drawn inside the page's moved
    // drawing), per page.
    let crosses = |tile: &Tile| -> Vec<[i64; 2]> {
        parse(&tile.svg)
            .iter()
            .filter(|e| e.name == "circle" && e.attr("stroke") == Some("#d40000"))
            .map(|e| {
                [
                    (1e3 * e.number("cx")).round() as i64,
                    (1e3 * e.number("cy")).round() as i64,
                ]
            })
            .collect()
    };
    let at = |r: usize, c: usize| &tiled.tiles[(r - 1) * tiled.cols + c - 1];
    let (left, right) = (crosses(at(1, 1)), crosses(at(1, 2)));
    let shared: Vec<_> = left.iter().filter(|p| right.contains(p)).collect();
    assert!(!shared.is_empty(), "{left:?} {right:?}");
    let (upper, lower) = (crosses(at(1, 1)), crosses(at(2, 1)));
    assert!(upper.iter().any(|p| lower.contains(p)));
}

#[test]
fn bad_layouts_and_pages_are_errors() {
    let bad = DeckLayout {
        ring_radius_m: -1.0,
        ..DeckLayout::paper()
    };
    assert!(matches!(PatternDrawing::new(&bad), Err(PatternError::Layout(_))));
    assert!(pattern_svg(&bad)
        .unwrap_err()
        .to_string()
        .contains("ring_radius_m"));
    let drawing = PatternDrawing::new(&DeckLayout::paper()).unwrap();
    for (margin_mm, overlap_mm, option) in [
        (2.0, 10.0, "margin_mm"),
        (f64::NAN, 10.0, "margin_mm"),
        (12.0, 1.0, "overlap_mm"),
        (80.0, 10.0, "margin_mm"),
    ] {
        let options = TileOptions {
            paper: Paper::A4,
            margin_mm,
            overlap_mm,
        };
        let e = TiledPattern::new(&drawing, &options).unwrap_err();
        assert!(
            matches!(e, PatternError::Page { option: o, .. } if o == option),
            "{e}"
        );
    }
}

//! The deck's pattern for printing or painting: SVG at true scale from the deck layout
//! (`common::deck`), as one sheet ([`PatternDrawing`]) or cut into pages of paper with an
//! overview ([`TiledPattern`]). Text generation only, no I/O: `deckwatch pattern` writes the
//! files.
//!
//! The sheet's user unit is the millimetre (`width="…mm"` and a view box in mm), so a viewer or
//! printer at 100 % draws every disc at its layout's size. What the sheet holds: the discs
//! white on a black square field (what the detector finds), the ring markers' numbers, an arrow
//! to the bow, dimension lines with their values (the centre disc's and the bow disc's
//! diameters, the ring's radius), a 100 mm check bar and a title with the layout's values.

mod drawing;
mod svg;
mod tiles;

pub use drawing::{PatternDrawing, CHECK_BAR_MM, CHECK_BAR_TEXT};
pub use tiles::{Paper, Tile, TileOptions, TiledPattern, MIN_MARGIN_MM, MIN_OVERLAP_MM};

use deckwatch_common::{DeckLayout, InvalidField};

/// Why no pattern could be drawn.
#[derive(Debug, Clone, PartialEq)]
pub enum PatternError {
    /// The deck layout is not valid (the field says which value).
    Layout(InvalidField),
    /// A page setting leaves no room: which (`margin_mm`, `overlap_mm`) and why.
    Page { option: &'static str, problem: String },
}

impl std::fmt::Display for PatternError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Layout(e) => write!(f, "deck layout: {e}"),
            Self::Page { option, problem } => write!(f, "{option}: {problem}"),
        }
    }
}

impl std::error::Error for PatternError {}

/// The layout's pattern as one SVG sheet at true scale.
pub fn pattern_svg(layout: &DeckLayout) -> Result<String, PatternError> {
    Ok(PatternDrawing::new(layout)?.svg())
}

#[cfg(test)]
mod tests;

//! deckwatch's runtime: everything between the algorithms and the operating system.
//!
//! - [`bus`]: the iceoryx2 transport (services, publishers, subscribers, the event loop).
//! - [`config`]: the one typed pipeline configuration every process reads.
//! - [`stage`]: the [`stage::Stage`] trait and the one runner of every stage process.
//! - [`stages`]: capture, detect, estimate and decide, wired to their algorithm crates, and the
//!   topology: the process table and the row of stages a frame passes.
//! - [`row`]: a row of stages (each one's output the next one's input), which the process table
//!   lists and the in-process chain runs.
//! - [`chain`]: the same stages in one process (`deckwatch inproc`, `deckwatch eval`).
//!
//! The algorithm crates (common, capture, detect, estimate, decide) know nothing of this crate;
//! see ARCHITECTURE.md.

pub mod bus;
pub mod chain;
pub mod config;
pub mod resim;
pub mod row;
pub mod stage;
pub mod stages;

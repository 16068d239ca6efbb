//! `deckwatch-link`: the MAVLink link to the autopilot (see `deckwatch_runtime::stages::link`).
fn main() -> std::process::ExitCode {
    deckwatch_runtime::stage::main::<deckwatch_runtime::stages::link::Link>()
}

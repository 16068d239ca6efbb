//! `deckwatch-record`: the flight recorder (see `deckwatch_runtime::stages::record`).
fn main() -> std::process::ExitCode {
    deckwatch_runtime::stage::main::<deckwatch_runtime::stages::record::Recorder>()
}

//! `deckwatch-detect`: the detect stage in a process of its own (see `deckwatch_runtime::stages::detect`).
fn main() -> std::process::ExitCode {
    deckwatch_runtime::stage::main::<deckwatch_runtime::stages::DetectStage>()
}

//! `deckwatch-decide`: the decide stage in a process of its own (see `deckwatch_runtime::stages::decide`).
fn main() -> std::process::ExitCode {
    deckwatch_runtime::stage::main::<deckwatch_runtime::stages::DecideStage>()
}

//! `deckwatch-capture`: the capture stage, the pipeline's source (see `deckwatch_runtime::stages::capture`).
fn main() -> std::process::ExitCode {
    deckwatch_runtime::stage::main::<deckwatch_runtime::stages::capture::Capture>()
}

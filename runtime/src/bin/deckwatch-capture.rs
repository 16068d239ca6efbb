//! `deckwatch-capture`: the capture stage in a process of its own (see
//! `deckwatch_runtime::stages::capture`).
fn main() -> std::process::ExitCode {
    deckwatch_runtime::stages::capture::main()
}

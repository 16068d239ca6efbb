//! `deckwatch-estimate`: the estimate stage in a process of its own (see `deckwatch_runtime::stages::estimate`).
fn main() -> std::process::ExitCode {
    deckwatch_runtime::stage::main::<deckwatch_runtime::stages::EstimateStage>()
}

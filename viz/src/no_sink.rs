//! A build without the `rerun` feature: the logging API without the rerun SDK. `off` works;
//! any other sink is refused, saying how to get it.

use crate::{Item, RerunConfig, RerunSink};
use crossbeam_channel::Receiver;
use std::path::Path;
use std::thread::JoinHandle;

fn not_built(sink: &str) -> String {
    format!(
        "rerun.sink = \"{sink}\": this build has no rerun logging (it was built without the \
         `rerun` feature, which is on by default); rebuild with it or set rerun.sink = \"off\""
    )
}

pub(crate) fn spawn_logging_thread(
    config: &RerunConfig,
    _stage: &str,
    _rx: Receiver<Item>,
) -> Result<JoinHandle<()>, String> {
    Err(not_built(config.sink.name()))
}

/// Stands for the launcher's rerun stream; never made in this build.
pub enum Viewer {}

impl Viewer {
    pub fn close(self) {
        match self {}
    }
}

pub fn open_viewer(config: &RerunConfig, _stage: &str) -> Result<Option<Viewer>, String> {
    match config.sink {
        RerunSink::Off => Ok(None),
        other => Err(not_built(other.name())),
    }
}

/// Nothing to merge: no stage of this build writes parts.
pub fn merge_parts(path: &Path, _stages: &[&str]) -> Result<u64, String> {
    Err(format!("{}: {}", path.display(), not_built("save")))
}

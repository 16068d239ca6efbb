//! A build without the `rerun` feature: the logging API without the rerun SDK. `off` works;
//! any other sink is refused, saying how to get it.

use crate::{Item, RerunConfig, RerunSink, RunDescription, VizError};
use crossbeam_channel::Receiver;
use std::path::Path;
use std::thread::JoinHandle;

pub(crate) fn spawn_logging_thread(
    config: &RerunConfig,
    _stage: &str,
    _rx: Receiver<Item>,
) -> Result<JoinHandle<()>, VizError> {
    Err(VizError::NotBuilt {
        sink: config.sink.name(),
    })
}

/// Stands for the launcher's rerun stream; never made in this build.
pub enum Viewer {}

impl Viewer {
    pub fn close(self) {
        match self {}
    }
}

pub fn open_viewer(
    config: &RerunConfig,
    _stage: &str,
    _about: &RunDescription,
) -> Result<Option<Viewer>, VizError> {
    match config.sink {
        RerunSink::Off => Ok(None),
        other => Err(VizError::NotBuilt { sink: other.name() }),
    }
}

/// Nothing to merge: no stage of this build writes parts.
pub fn merge_parts(path: &Path, _stages: &[&str]) -> Result<u64, VizError> {
    Err(VizError::File {
        path: path.to_path_buf(),
        message: VizError::NotBuilt { sink: "save" }.to_string(),
    })
}

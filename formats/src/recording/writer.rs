//! Writing a recording folder frame by frame (`camera.json`, `frames.csv`, the PNGs).

use super::*;

/// Writes a recording: `camera.json` at creation, then one PNG and one `frames.csv` row per frame.
/// Each row is flushed after its image is complete, so an interrupted recording stays readable.
pub struct RecordingWriter {
    dir: PathBuf,
    camera: CameraModel,
    csv: csv::Writer<BufWriter<File>>,
    truth_columns: TruthColumns,
    last: Option<(u64, u64)>,
    frames_written: u64,
}

impl RecordingWriter {
    /// Creates the folder (it must not hold a recording already) and writes `camera.json` and
    /// the header of `frames.csv` with the chosen ground-truth columns.
    pub fn create(
        dir: impl AsRef<Path>,
        camera: &CameraModel,
        deck: &DeckLayout,
        truth_columns: TruthColumns,
    ) -> Result<Self, RecordingError> {
        let dir = dir.as_ref().to_path_buf();
        camera
            .validate()
            .map_err(|m| RecordingError::new(&dir, m.to_string()))?;
        deck.validate()
            .map_err(|m| RecordingError::new(&dir, m.to_string()))?;
        if dir.join(FRAMES_FILE).exists() {
            return Err(RecordingError::new(
                &dir,
                "already holds a recording (frames.csv exists); choose a new folder",
            ));
        }
        std::fs::create_dir_all(dir.join(IMAGES_DIR))
            .map_err(|e| RecordingError::new(&dir, format!("cannot create: {e}")))?;
        write_camera_json(&dir, camera, deck)?;
        let path = dir.join(FRAMES_FILE);
        let file =
            File::create(&path).map_err(|e| RecordingError::new(&path, format!("cannot create: {e}")))?;
        let mut csv = csv::Writer::from_writer(BufWriter::new(file));
        let mut header = vec!["index", "timestamp_ns", "file"];
        header.extend(
            TRUTH_COLUMNS
                .iter()
                .zip(truth_columns)
                .filter(|(_, on)| *on)
                .map(|(n, _)| *n),
        );
        csv.write_record(&header)
            .and_then(|_| csv.flush().map_err(csv::Error::from))
            .map_err(|e| RecordingError::new(&path, format!("cannot write: {e}")))?;
        Ok(Self {
            dir,
            camera: *camera,
            csv,
            truth_columns,
            last: None,
            frames_written: 0,
        })
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn frames_written(&self) -> u64 {
        self.frames_written
    }

    /// Writes one frame: its PNG, then its row (indices must increase, timestamps not decrease).
    pub fn write_frame(
        &mut self,
        index: u64,
        timestamp_ns: u64,
        image: GrayView<'_>,
        truth: &GroundTruth,
    ) -> Result<(), RecordingError> {
        let csv_path = self.dir.join(FRAMES_FILE);
        if (image.width(), image.height()) != (self.camera.width as usize, self.camera.height as usize) {
            return Err(RecordingError::new(
                &csv_path,
                format!(
                    "frame {index} is {}x{}, the recording's camera is {}x{}",
                    image.width(),
                    image.height(),
                    self.camera.width,
                    self.camera.height
                ),
            ));
        }
        if let Some((pi, pt)) = self.last {
            if index <= pi || timestamp_ns < pt {
                return Err(RecordingError::new(
                    &csv_path,
                    format!("frame {index} at {timestamp_ns} ns does not follow frame {pi} at {pt} ns"),
                ));
            }
        }
        let file = format!("{IMAGES_DIR}/{index:06}.png");
        encode_gray_png(&self.dir.join(&file), image)?;
        let mut row = vec![index.to_string(), timestamp_ns.to_string(), file];
        for (v, on) in truth.values().iter().zip(self.truth_columns) {
            if on {
                // Shortest representation that round-trips exactly.
                row.push(v.map_or_else(|| "nan".to_string(), |x| format!("{x:?}")));
            }
        }
        self.csv
            .write_record(&row)
            .and_then(|_| self.csv.flush().map_err(csv::Error::from))
            .map_err(|e| RecordingError::new(&csv_path, format!("cannot write: {e}")))?;
        self.last = Some((index, timestamp_ns));
        self.frames_written += 1;
        Ok(())
    }

    /// Flushes and closes the recording.
    pub fn finish(mut self) -> Result<u64, RecordingError> {
        let path = self.dir.join(FRAMES_FILE);
        self.csv
            .flush()
            .map_err(|e| RecordingError::new(&path, format!("cannot write: {e}")))?;
        Ok(self.frames_written)
    }
}

//! The pipeline configuration: one typed schema for every stage and the launcher, parsed and
//! validated here only. Each section is defined by the crate whose part it configures
//! (`[sim]`/`[image]`/`[replay]`/`[libcamera]`/`[source]` by capture, `[estimate]` by estimate,
//! `[decide]` by decide, `[rerun]` by viz, `[bus]` by the transport); this module puts them
//! together, and every process (launcher and stages) reads the same file through it. Unknown
//! keys are errors; errors name the file, the line and the key.

use crate::bus::{BusConfig, BusError};
use deckwatch_capture::camera::CameraConfig;
use deckwatch_capture::source::{CaptureConfig, ReplayConfig, SourceConfig, SourceError};
use deckwatch_common::messages::{EstimatorKind, FrameSource};
use deckwatch_common::vehicle::{VehicleAttitudeSource, VehicleConfig};
use deckwatch_common::InvalidField;
use deckwatch_decide::{DecisionConfig, HeaveUse};
use deckwatch_estimate::EstimateConfig;
use deckwatch_flight::RecordConfig;
use deckwatch_link::LinkConfig;
use deckwatch_sim::scenario::SimulationArgs;
use deckwatch_sim::sim::ImageArgs;
use deckwatch_viz::RerunConfig;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// `[supervisor]`: how the launcher runs the stages.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct SupervisorConfig {
    /// First restart delay of a crashed stage; doubles with each further crash in a row.
    pub restart_backoff_ms: u64,
    pub max_backoff_ms: u64,
    /// Restarts allowed per stage within `restart_window_ms` before the run is given up (0:
    /// never restart). A sliding window: a long mission with a rare crash never runs out.
    pub max_restarts: u32,
    pub restart_window_ms: u64,
    /// A stage that ran this long before crashing starts its backoff afresh.
    pub healthy_after_ms: u64,
    /// How long a stage may take to connect at start (and to send its first heartbeat after a
    /// restart).
    pub ready_timeout_ms: u64,
    /// A stage whose heartbeats stop for this long (stopped, deadlocked, stuck in a step) is
    /// killed and restarted.
    pub hang_timeout_ms: u64,
    /// How long a stage may take to exit after SIGTERM before it is killed.
    pub stop_timeout_ms: u64,
    /// After the source is exhausted: stop once no decision came for this long.
    pub drain_ms: u64,
    /// Live status line period.
    pub status_interval_ms: u64,
}

impl Default for SupervisorConfig {
    fn default() -> Self {
        Self {
            restart_backoff_ms: 250,
            max_backoff_ms: 8000,
            max_restarts: 10,
            restart_window_ms: 600_000,
            healthy_after_ms: 10_000,
            ready_timeout_ms: 10_000,
            hang_timeout_ms: 1000,
            stop_timeout_ms: 3000,
            drain_ms: 500,
            status_interval_ms: 1000,
        }
    }
}

/// The whole pipeline configuration (TOML).
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct PipelineConfig {
    pub bus: BusConfig,
    pub source: SourceConfig,
    pub sim: SimulationArgs,
    pub image: ImageArgs,
    pub replay: ReplayConfig,
    pub libcamera: CameraConfig,
    pub vehicle: VehicleConfig,
    pub estimate: EstimateConfig,
    pub decide: DecisionConfig,
    pub link: LinkConfig,
    pub supervisor: SupervisorConfig,
    pub rerun: RerunConfig,
    pub record: RecordConfig,
}

/// What is wrong with a configuration, and where.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file cannot be read, or is larger than [`MAX_CONFIG_FILE_BYTES`] (the error names it).
    #[error(transparent)]
    Read(#[from] deckwatch_common::files::FileReadError),
    /// TOML syntax, an unknown key or a value of the wrong type (the message has the line).
    #[error("{file}: {message}")]
    Parse { file: String, message: String },
    /// A value out of range: `section.key: problem`.
    #[error("{file}: {key}: {problem}")]
    Invalid {
        file: String,
        key: String,
        problem: String,
    },
    /// The source's sections (`[source]`, `[sim]`, `[image]`, `[replay]`, `[libcamera]`).
    #[error("{file}: {source}")]
    Source { file: String, source: SourceError },
    #[error(transparent)]
    Bus(#[from] BusError),
}

impl ConfigError {
    /// A section's bad value in `file`: every section states one as an `InvalidField` (its key
    /// without the section), and this is where the section and the file are put on it.
    pub fn in_section(file: &str, section: &str, e: InvalidField) -> Self {
        ConfigError::Invalid {
            file: file.to_string(),
            key: format!("{section}.{}", e.field),
            problem: e.problem,
        }
    }
}

/// The largest pipeline configuration read (bytes): every section with its comments is ~10 KB,
/// so a file of a megabyte is no configuration, and is refused before it is read.
pub const MAX_CONFIG_FILE_BYTES: u64 = 1 << 20;

/// The name configuration errors give a configuration that came from no file.
pub const DEFAULTS: &str = "(defaults)";

impl PipelineConfig {
    /// Parses `text` (from `file`, for messages). Values are checked by [`Self::validate`].
    pub fn from_toml(file: &str, text: &str) -> Result<Self, ConfigError> {
        let parse_error = |e: toml::de::Error| ConfigError::Parse {
            file: file.to_string(),
            message: e.to_string(),
        };
        // A key of `[decide]` that moved (the forecaster's tuning is `[decide.forecast]` now) is
        // named with its new place, not as an unknown field.
        let table: toml::Table = toml::from_str(text).map_err(parse_error)?;
        if let Some(decide) = table.get("decide").and_then(toml::Value::as_table) {
            if let Some((key, to)) = decide
                .keys()
                .find_map(|key| deckwatch_decide::decision::moved_key(key).map(|to| (key, to)))
            {
                return Err(ConfigError::Invalid {
                    file: file.to_string(),
                    key: format!("decide.{key}"),
                    problem: to.to_string(),
                });
            }
        }
        toml::from_str(text).map_err(parse_error)
    }

    /// Reads (at most [`MAX_CONFIG_FILE_BYTES`]) and parses a file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = deckwatch_common::files::read_bounded_to_string(path, MAX_CONFIG_FILE_BYTES)?;
        Self::from_toml(&path.display().to_string(), &text)
    }

    /// The file's configuration, or the defaults without one.
    pub fn load_or_default(path: Option<&Path>) -> Result<Self, ConfigError> {
        path.map_or_else(|| Ok(Self::default()), Self::load)
    }

    /// What a run of this configuration is, as (key, value) pairs: the version, the source
    /// (and its scenario, recording or camera), the estimator, the domain and the host. Shown as
    /// the rerun recording's properties and written in a flight recording's metadata.
    pub fn run_properties(&self) -> Vec<(String, String)> {
        use deckwatch_common::messages::FrameSource;
        let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default();
        let mut out = vec![
            ("version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
            ("source".to_string(), self.source.kind.name().to_string()),
        ];
        match self.source.kind {
            FrameSource::Simulator => {
                out.push(("scenario".into(), self.sim.scenario.name().into()));
                out.push(("seed".into(), self.sim.seed.to_string()));
                out.push(("rate_hz".into(), self.sim.rate.to_string()));
            }
            FrameSource::Replay => {
                let path = self.replay.recording.as_ref().map(|p| p.display().to_string());
                out.push(("recording".into(), path.unwrap_or_default()));
            }
            _ => out.push(("camera".into(), format!("{:?}", self.libcamera))),
        }
        out.extend([
            (
                "estimator".to_string(),
                self.estimate.estimator.name().to_string(),
            ),
            ("domain".to_string(), self.bus.domain.clone()),
            ("host".to_string(), host.trim().to_string()),
        ]);
        out
    }

    /// Serialises the configuration (`--print-config`, and the file the launcher hands the
    /// stages).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("every configuration value has a TOML form")
    }

    /// Checks every section the way its stage will (without opening the source). `file` names
    /// the configuration in the error.
    pub fn validate(&self, file: &str) -> Result<(), ConfigError> {
        let invalid = |key: String, problem: String| ConfigError::Invalid {
            file: file.to_string(),
            key,
            problem,
        };
        let in_section =
            |section: &'static str| move |e: InvalidField| ConfigError::in_section(file, section, e);
        self.bus.settings(1).validate().map_err(in_section("bus"))?;
        self.capture().check().map_err(|source| ConfigError::Source {
            file: file.to_string(),
            source,
        })?;
        self.decide.validate().map_err(in_section("decide"))?;
        // The flying pipeline reserves for the autopilot's own errors: they pass one for one
        // into the deck's angles and heave rate, where the forecast's band cannot see them, and
        // stated as 0 they cleared unsafe touchdowns (`DecisionConfig::vehicle_attitude_error_deg`).
        // The evaluations (`decide-eval`, `trials`) may state an exact simulated autopilot.
        for (key, value) in [
            (
                "decide.vehicle_attitude_error_deg",
                self.decide.vehicle_attitude_error_deg,
            ),
            (
                "decide.vertical_speed_error_mps",
                self.decide.vertical_speed_error_mps,
            ),
        ] {
            if !(value > 0.0) {
                return Err(invalid(
                    key.into(),
                    format!("must be above 0 in the flying pipeline: no autopilot knows its attitude and vertical speed exactly, and the decision must reserve for their errors (the defaults: {} deg, {} m/s); got {value}", deckwatch_decide::decision::AUTOPILOT_ATTITUDE_ERROR_DEG, deckwatch_decide::decision::AUTOPILOT_VERTICAL_SPEED_ERROR_MPS),
                ));
            }
        }
        self.vehicle.validate().map_err(in_section("vehicle"))?;
        self.link.validate().map_err(in_section("link"))?;
        if self.link.signing == deckwatch_link::config::SigningMode::Required {
            // The key itself, now (`--print-config` too), not first when the link starts: a weak
            // or readable key is refused with the configuration that names it.
            deckwatch_link::signing::load_key(Path::new(&self.link.signing_key_file))
                .map_err(|e| invalid("link.signing_key_file".into(), e.to_string()))?;
        }
        if self.source.kind == FrameSource::Libcamera
            && self.vehicle.attitude == VehicleAttitudeSource::Frames
        {
            return Err(invalid(
                "vehicle.attitude".into(),
                "a camera's frames carry no vehicle attitude: use \"autopilot\" (the link process), or \"level\" for a gimballed camera".into(),
            ));
        }
        if self.decide.heave == HeaveUse::Required {
            let no_pose = self.estimate.estimator != EstimatorKind::FullPose && !self.estimate.compare;
            if no_pose {
                return Err(invalid(
                    "decide.heave".into(),
                    "the deck's heave needs the full pose (estimate.estimator = \"full-pose\" or estimate.compare = true); or set heave = \"off\" to decide on roll and pitch alone".into(),
                ));
            }
            if self.vehicle.attitude == VehicleAttitudeSource::Level {
                return Err(invalid(
                    "decide.heave".into(),
                    "the deck's heave needs the vehicle's height, which vehicle.attitude = \"level\" does not give: use \"autopilot\" or \"frames\", or set heave = \"off\" to decide on roll and pitch alone".into(),
                ));
            }
        }
        self.rerun.validate().map_err(in_section("rerun"))?;
        self.record.validate().map_err(in_section("record"))?;
        if self.record.records_frames() && self.bus.frame_subscribers < 2 {
            return Err(invalid(
                "bus.frame_subscribers".into(),
                "recording frames needs 2 at least (detect and the recorder)".into(),
            ));
        }
        let s = &self.supervisor;
        // Two heartbeat periods at least, or a busy machine looks hung.
        let min_hang_ms = 2 * deckwatch_common::messages::StageHeartbeat::PERIOD_NS / 1_000_000;
        if s.hang_timeout_ms < min_hang_ms {
            return Err(invalid(
                "supervisor.hang_timeout_ms".into(),
                format!("must be at least {min_hang_ms} (two heartbeat periods)"),
            ));
        }
        for (k, v) in [
            ("ready_timeout_ms", s.ready_timeout_ms),
            ("stop_timeout_ms", s.stop_timeout_ms),
            ("status_interval_ms", s.status_interval_ms),
            ("restart_backoff_ms", s.restart_backoff_ms),
            ("restart_window_ms", s.restart_window_ms),
        ] {
            if v == 0 {
                return Err(invalid(format!("supervisor.{k}"), "must be positive".into()));
            }
        }
        Ok(())
    }

    /// The capture stage's sections.
    pub fn capture(&self) -> CaptureConfig {
        CaptureConfig {
            source: self.source.clone(),
            sim: self.sim.clone(),
            image: self.image.clone(),
            replay: self.replay.clone(),
            libcamera: self.libcamera.clone(),
            vehicle: self.vehicle.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::{EstimatorKind, FrameSource};

    #[test]
    fn the_forecasters_tuning_has_its_own_table_and_old_keys_say_where_they_went() {
        let decide = |text: &str| PipelineConfig::from_toml("p.toml", text).unwrap().decide;
        assert_eq!(decide(""), DecisionConfig::default());
        let tuned = decide("[decide.forecast]\nkind = \"ar\"\nwindow_s = 60.0\norder = 48\n");
        assert_eq!((tuned.ar().window_s, tuned.ar().order), (60.0, 48));
        assert_eq!(
            tuned.ar().min_history_s,
            DecisionConfig::default().ar().min_history_s
        );
        // The autopilot's errors, which no band sees, are stated on their own.
        let ar = decide("");
        assert_eq!(ar.vertical_speed_error_mps, 0.05);
        assert_eq!(ar.vehicle_attitude_error_deg, 0.2);
        assert_eq!(
            decide("[decide]\nvertical_speed_error_mps = 0.01\n").vertical_speed_error_mps,
            0.01
        );
        // A key that moved names its new place; one that was removed says why.
        for (text, key, place) in [
            (
                "[decide]\nwindow_s = 60.0\n",
                "decide.window_s",
                "[decide.forecast] window_s",
            ),
            (
                "[decide]\nar_order = 48\n",
                "decide.ar_order",
                "[decide.forecast] order",
            ),
            (
                "[decide]\npredictor = \"ar\"\n",
                "decide.predictor",
                "[decide.forecast] kind",
            ),
            (
                "[decide]\nmargin_deg = 0.5\n",
                "decide.margin_deg",
                "less the margin",
            ),
            (
                "[decide]\nerror_memory_s = 6.0\n",
                "decide.error_memory_s",
                "sinusoid",
            ),
        ] {
            let m = PipelineConfig::from_toml("p.toml", text).unwrap_err().to_string();
            assert!(
                m.contains("p.toml") && m.contains(key) && m.contains(place),
                "{m}"
            );
        }
        // An unknown kind, or a key of no kind, is an error naming it.
        for (text, word) in [
            ("[decide.forecast]\nkind = \"crystal-ball\"\n", "crystal-ball"),
            ("[decide.forecast]\nkind = \"ar\"\ncomponents = 4\n", "components"),
        ] {
            let m = PipelineConfig::from_toml("p.toml", text).unwrap_err().to_string();
            assert!(m.contains("p.toml") && m.contains(word), "{m}");
        }
    }

    #[test]
    fn errors_name_file_line_and_key() {
        let e = PipelineConfig::from_toml("p.toml", "[sim]\nscenari = \"ship\"\n").unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("p.toml") && m.contains("scenari") && m.contains("line 2"),
            "{m}"
        );
        let m = PipelineConfig::from_toml("p.toml", "[sim]\nrate = \"fast\"\n")
            .unwrap_err()
            .to_string();
        assert!(m.contains("rate"), "{m}");
        // Choices are typed: an unknown one is a parse error naming the key's value.
        for (text, word) in [
            ("[source]\nkind = \"usb\"\n", "usb"),
            ("[estimate]\nestimator = \"magic\"\n", "magic"),
            ("[decide]\nheave = \"crystal-ball\"\n", "crystal-ball"),
            ("[rerun]\nsink = \"printer\"\n", "printer"),
            ("[sim]\nscenario = \"moon\"\n", "moon"),
            ("[image]\nlook = \"fancy\"\n", "fancy"),
            ("[nonsense]\nx = 1\n", "nonsense"),
        ] {
            let m = PipelineConfig::from_toml("p.toml", text).unwrap_err().to_string();
            assert!(m.contains("p.toml") && m.contains(word), "{m}");
        }
        let c = PipelineConfig::from_toml("p.toml", "[decide]\nmax_age_ms = -1\n").unwrap();
        let m = c.validate("p.toml").unwrap_err().to_string();
        assert!(m.contains("p.toml") && m.contains("decide.max_age_ms"), "{m}");
        let c = PipelineConfig::from_toml("p.toml", "[supervisor]\nready_timeout_ms = 0\n").unwrap();
        let m = c.validate("p.toml").unwrap_err().to_string();
        assert!(m.contains("supervisor.ready_timeout_ms"), "{m}");
        let c = PipelineConfig::from_toml("p.toml", "[source]\nkind = \"replay\"\n").unwrap();
        let m = c.validate("p.toml").unwrap_err().to_string();
        assert!(m.contains("replay.recording"), "{m}");
        // The heave needs a full pose and a vehicle height; `off` says there is none.
        for text in [
            "[estimate]\nestimator = \"paper-atan2\"\ncompare = false\n",
            "[vehicle]\nattitude = \"level\"\n",
        ] {
            let c = PipelineConfig::from_toml("p.toml", text).unwrap();
            let m = c.validate("p.toml").unwrap_err().to_string();
            assert!(m.contains("decide.heave") && m.contains("\"off\""), "{m}");
            let off = format!("{text}[decide]\nheave = \"off\"\n");
            PipelineConfig::from_toml("p.toml", &off)
                .unwrap()
                .validate("p.toml")
                .unwrap();
        }
        let c = PipelineConfig::from_toml("p.toml", "[bus]\ndomain = \"Not Ok\"\n").unwrap();
        let m = c.validate("p.toml").unwrap_err().to_string();
        assert!(m.contains("bus") && m.contains("Not Ok"), "{m}");
        let m = PipelineConfig::load(Path::new("/nonexistent/x.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("/nonexistent/x.toml") && m.contains("cannot read"),
            "{m}"
        );
    }

    /// A sparse 10 GB configuration is refused from its size, naming the file and the limit.
    #[test]
    fn a_configuration_beyond_its_bound_is_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("huge.toml");
        std::fs::File::create(&path).unwrap().set_len(10 << 30).unwrap();
        let m = PipelineConfig::load(&path).unwrap_err().to_string();
        assert!(
            m.contains("huge.toml") && m.contains("10737418240 bytes") && m.contains("1048576 bytes"),
            "{m}"
        );
    }

    #[test]
    fn typed_choices_read_their_names_and_round_trip() {
        let text = "[source]\nkind = \"replay\"\n[replay]\nrecording = \"r\"\n\
                    [estimate]\nestimator = \"paper-fitted-major-axis\"\n\
                    [decide]\nheave = \"off\"\n[rerun]\nsink = \"save\"\npath = \"x.rrd\"\n\
                    [sim]\nscenario = \"nodeck\"\n";
        let c = PipelineConfig::from_toml("t", text).unwrap();
        assert_eq!(c.source.kind, FrameSource::Replay);
        assert_eq!(c.estimate.estimator, EstimatorKind::PaperFittedMajorAxis);
        assert_eq!(c.decide.heave, HeaveUse::Off);
        assert_eq!(c.rerun.sink, deckwatch_viz::RerunSink::Save);
        assert_eq!(c.sim.scenario, deckwatch_sim::Scenario::NoDeck);
        let again = PipelineConfig::from_toml("again", &c.to_toml()).unwrap();
        assert_eq!(again, c);
        assert_eq!(
            PipelineConfig::from_toml("t", "").unwrap(),
            PipelineConfig::default()
        );
        PipelineConfig::default().validate(DEFAULTS).unwrap();
    }
}

//! What the first approach of `deckwatch trials` logs to rerun, and the touchdown's verdict as
//! the viewer shows it.

use deckwatch_decide::DecisionConfig;
use deckwatch_runtime::chain::ChainOutput;
use deckwatch_trials::{ApproachModel, ApproachOutcome};

/// What the first approach logs to rerun: the frames (downscaled), the markers, the deck's true
/// and measured angles, the decisions, the vehicle's height over the deck, the commits and
/// go-arounds, and the touchdown's verdict.
pub(super) struct TrialLog {
    logger: deckwatch_viz::Logger,
    viewer: Option<deckwatch_viz::Viewer>,
    view: deckwatch_viz::entities::DecisionView,
    path: std::path::PathBuf,
}

impl TrialLog {
    const VIEW_PART: &str = "trial-view";
    const PART: &str = "trial";

    pub(super) fn start(path: &std::path::Path, c: &DecisionConfig, about: String) -> Result<Self, String> {
        let config = deckwatch_viz::RerunConfig {
            sink: deckwatch_viz::RerunSink::Save,
            path: Some(path.to_path_buf()),
            queue: 1 << 16,
            recording_id: Some(format!("deckwatch-trial-{}", std::process::id())),
            layout: deckwatch_viz::Layout::Trial,
            ..Default::default()
        };
        let description = deckwatch_viz::RunDescription {
            name: about,
            ..Default::default()
        };
        let viewer = deckwatch_viz::open_viewer(&config, Self::VIEW_PART, &description)
            .map_err(|e| format!("--rrd: {e}"))?;
        let logger = deckwatch_viz::Logger::start(&config, Self::PART)
            .map_err(|e| format!("--rrd: {e}"))?
            .ok_or("--rrd: no rerun sink")?;
        Ok(Self {
            logger,
            viewer,
            view: deckwatch_viz::entities::DecisionView::new(c.max_abs_roll_deg, c.max_abs_pitch_deg),
            path: path.to_path_buf(),
        })
    }

    pub(super) fn frame(&mut self, o: &ChainOutput, pixels: &[u8], over_deck_m: f64) {
        let d = &o.decision;
        let (seq, t) = (d.stamp.seq, d.stamp.times.captured_ns);
        let (w, h) = (d.context.camera.width as usize, d.context.camera.height as usize);
        self.logger.log(self.logger.image(seq, t, pixels, w, h, w));
        for item in deckwatch_viz::entities::marker_items(&o.markers, None) {
            self.logger.log(item);
        }
        for item in deckwatch_viz::entities::truth_items(seq, t, &d.context.truth) {
            self.logger.log(item);
        }
        for item in deckwatch_viz::entities::attitude_items(&o.attitude, None) {
            self.logger.log(item);
        }
        for item in self.view.items(d) {
            self.logger.log(item);
        }
        self.logger.log(deckwatch_viz::Item {
            frame: Some(seq),
            time_ns: t,
            kind: deckwatch_viz::ItemKind::Scalars(vec![(
                deckwatch_viz::entities::VEHICLE_OVER_DECK.to_string(),
                over_deck_m,
            )]),
        });
    }

    pub(super) fn text(&self, time_ns: u64, text: String) {
        self.logger.log(deckwatch_viz::Item {
            frame: None,
            time_ns,
            kind: deckwatch_viz::ItemKind::Text(text),
        });
    }

    pub(super) fn finish(self, time_ns: u64, verdict: String) -> Result<(), String> {
        self.logger.log(deckwatch_viz::Item {
            frame: None,
            time_ns,
            kind: deckwatch_viz::ItemKind::Document {
                entity: deckwatch_viz::entities::DECISION_NOW,
                markdown: verdict,
            },
        });
        self.logger.finish();
        if let Some(v) = self.viewer {
            v.close();
        }
        deckwatch_viz::merge_parts(&self.path, &[Self::VIEW_PART, Self::PART])
            .map_err(|e| format!("--rrd: {e}"))?;
        Ok(())
    }
}

/// The verdict shown in the viewer at the end of a logged approach.
pub(super) fn verdict_markdown(o: &ApproachOutcome, model: &ApproachModel, c: &DecisionConfig) -> String {
    match &o.touchdown {
        Some(v) => format!(
            "# Touchdown at {:.1} s: {}\n\n| | at contact | limit |\n|---|---|---|\n| deck roll | {:.2} deg | {} deg |\n| deck pitch | {:.2} deg | {} deg |\n| roll rate | {:.2} deg/s | {} deg/s |\n| pitch rate | {:.2} deg/s | {} deg/s |\n| heave rate | {:.2} m/s | {} m/s |\n| vehicle against deck | {:.2} deg | {} deg |\n\n{} commits, {} go-arounds",
            v.t_s,
            if v.safe() { "SAFE".to_string() } else { format!("UNSAFE ({})", v.violations.join(", ")) },
            v.deck.roll_deg,
            c.max_abs_roll_deg,
            v.deck.pitch_deg,
            c.max_abs_pitch_deg,
            v.deck.roll_rate_dps,
            c.max_abs_roll_rate_dps,
            v.deck.pitch_rate_dps,
            c.max_abs_pitch_rate_dps,
            v.deck.heave_rate_mps,
            c.max_abs_heave_rate_mps,
            v.relative_tilt_deg,
            model.max_relative_tilt_deg,
            o.commits,
            o.go_arounds
        ),
        None => format!(
            "# No touchdown in {} s\n\n{} commits, {} go-arounds",
            model.max_approach_s, o.commits, o.go_arounds
        ),
    }
}

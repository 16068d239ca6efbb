//! `deckwatch trials`: closed-loop landings. A simulated vehicle arrives over the deck of a
//! spectrum sea, hovers, and lands when the rule says so: the frames are rendered from the true
//! deck and the vehicle's own path, the stage chain (the processes' stages, in one process, on
//! a simulated clock) turns them into attitudes and decisions, and the simulated autopilot acts
//! on the decision state as it would arrive over the link (commit on a fresh ClearToLand,
//! go around on Abort). Each touchdown is judged at contact against the true deck. The same
//! approaches are flown by the naive rule (current angles within the limits) and by an oracle
//! that knows the future motion.

use deckwatch_common::messages::{FrameSource, LandingDecision, VehicleSample};
use deckwatch_common::vehicle::VehicleAttitudeSource;
use deckwatch_runtime::chain::{SimulatedClock, StageChain};
use deckwatch_runtime::config::{ConfigError, PipelineConfig};
use deckwatch_sim::landing::SharedFlightPath;
use deckwatch_sim::motion::SpectrumShipMotion;
use deckwatch_sim::motion_file::RecordedShipMotion;
use deckwatch_trials::{
    fly_approach, oracle_approach, Approach, ApproachModel, ApproachOutcome, ApproachTiming, ApproachWorld,
    ClosedLoopPipeline, FrameFaultModel, FrameFaults, FrameStep, PipelineRule, WorldError,
};
use std::sync::{Arc, Mutex};
use std::time::Instant;

#[derive(clap::Args, Debug, Clone)]
#[command(args_conflicts_with_subcommands = true)]
pub struct TrialsArgs {
    #[command(subcommand)]
    pub command: Option<TrialsCommand>,
    /// Fly only part K of N of the job list (`--shard 2/8`: jobs 1, 9, 17, ... counted from 0):
    /// the parts of N runs together are the whole, and `trials merge` of their `--json` outputs
    /// is the report of one run, bit for bit.
    #[arg(long)]
    pub shard: Option<String>,
    /// Sea states of the spectrum seas (3-6).
    #[arg(long, value_delimiter = ',', default_value = "3,4,5,6")]
    pub sea_states: Vec<u32>,
    /// Seeds (the sea's waves, the vehicle's sway, the faults).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    pub seeds: Vec<u64>,
    /// Mean headings of the waves off the bow (deg; 0 head seas, 90 beam seas).
    #[arg(long, value_delimiter = ',', default_value = "30,75")]
    pub headings_deg: Vec<f64>,
    /// The ship's motion from a file (CSV: `time_s,roll_deg,pitch_deg,heave_m`, optional
    /// `yaw_deg`; docs/recording.md, "Ship motion from a file"): the rendered deck follows it, and the
    /// report's sea is `0`. `--sea-states` and `--headings-deg` are unused; approach k starts
    /// 421 k s into the file (wrapped to fit its length; with a watch, 421 k s after it).
    #[arg(long)]
    pub motion_csv: Option<std::path::PathBuf>,
    /// Approaches per sea state, seed and heading (each starts at a different time of the sea).
    #[arg(long, default_value_t = 10)]
    pub approaches: u32,
    /// Rules flown: `deckwatch` (the decision), `naive`, `oracle`.
    #[arg(long, value_delimiter = ',', default_value = "deckwatch,naive,oracle")]
    pub rules: Vec<String>,
    /// Frame rate (Hz).
    #[arg(long, default_value_t = 10.0)]
    pub rate: f64,
    /// Image size (the camera preset scaled to it).
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// The vehicle's sway in hover, as a share of a hovering quadrotor's in wind (1: roll up to
    /// 9 deg).
    #[arg(long, default_value_t = 0.3)]
    pub sway: f64,
    /// Where the vehicle waits: its camera's height over the deck, which it follows on its range
    /// finder (m); with `--hold-height`, at the least over the deck's mean level.
    #[arg(long, default_value_t = 3.0)]
    pub hover_m: f64,
    /// While it waits it holds a height in W rather than following the deck: at least
    /// `--hover-m` over the deck's mean level, and `--wait-clearance-m` over the highest the
    /// deck has been in the last 30 s.
    #[arg(long)]
    pub hold_height: bool,
    /// Following the deck, its height lags the deck's by a first-order filter of this time
    /// constant (s; ArduPilot's SURFTRAK_TC defaults to 1 s); 0 follows it exactly.
    #[arg(long, default_value_t = 1.0)]
    pub follow_lag_s: f64,
    /// With `--hold-height`: the least height of the camera over the deck's highest (m).
    #[arg(long, default_value_t = 2.5)]
    pub wait_clearance_m: f64,
    /// The longest approach (s), from when the landing is asked for.
    #[arg(long, default_value_t = 240.0)]
    pub max_approach_s: f64,
    /// The vehicle holds over the deck this long before the landing is asked for (s): the
    /// pipeline sees the deck and decides, nothing is acted on, and the approach's times
    /// (`--max-approach-s`, the wait) count from the request. 0: asked for on arrival.
    #[arg(long, default_value_t = 0.0)]
    pub watch_before_s: f64,
    /// Each stage's time on the simulated clock (ms): capture -> decision is three of them.
    #[arg(long, default_value_t = 2.0)]
    pub stage_latency_ms: f64,
    /// Faults: share of frames lost between capture and detect.
    #[arg(long, default_value_t = 0.0)]
    pub drop_share: f64,
    /// Faults: specular glints per frame.
    #[arg(long, default_value_t = 0)]
    pub glints: u32,
    /// Faults: a frozen camera (the same image again, new timestamps) this often per minute...
    #[arg(long, default_value_t = 0.0)]
    pub frozen_per_min: f64,
    /// ... for this long each (s).
    #[arg(long, default_value_t = 2.0)]
    pub frozen_s: f64,
    /// Faults: outages of the autopilot's attitude stream per minute...
    #[arg(long, default_value_t = 0.0)]
    pub vehicle_outages_per_min: f64,
    /// ... each this long (s).
    #[arg(long, default_value_t = 1.0)]
    pub vehicle_outage_s: f64,
    /// Faults: white noise on each sample of the autopilot's height estimate (m, standard
    /// deviation)...
    #[arg(long, default_value_t = 0.0)]
    pub vehicle_height_noise_m: f64,
    /// ... and its slow error, given as the standard deviation of its rate (m/s): an
    /// estimator's vertical-speed error, which estimate's heave rate inherits.
    #[arg(long, default_value_t = 0.0)]
    pub vehicle_height_drift_mps: f64,
    /// Pipeline configuration whose `[decide]`, `[detect]`, `[estimate]` and `[image]` to use.
    #[arg(long)]
    pub config: Option<std::path::PathBuf>,
    /// Log the first approach of the decision's rule to this `.rrd` (the deck, the vehicle's
    /// height, the decisions, the verdict).
    #[arg(long)]
    pub rrd: Option<std::path::PathBuf>,
    /// With `--rrd`: the approach to log instead of the first, by its number in the job list
    /// (`job` in `--json`), to look at one approach of a run (an unsafe touchdown).
    #[arg(long, default_value_t = 0)]
    pub rrd_job: usize,
    /// JSON lines: one record per approach and rule (`{"approach": ...}`: the job's number, sea
    /// state, seed, heading, index, rule and outcome: commits, go-arounds and their reasons,
    /// the touchdown's verdict and time, the decisions by reason), then one object per sea
    /// state and rule and the totals, with the safety case (exact 95 % bounds).
    #[arg(long)]
    pub json: bool,
    /// Also fly the first this many approaches through the real processes at real time (the
    /// launcher's detect, estimate, decide and link; this process is the camera and the
    /// autopilot, over MAVLink on UDP), beside the same approaches in one process.
    #[arg(long, default_value_t = 0)]
    pub processes: usize,
    /// Approaches flown at once (default: one per core).
    #[arg(long, default_value_t = std::thread::available_parallelism().map_or(1, |n| n.get()))]
    pub threads: usize,
}

/// `deckwatch trials merge`.
#[derive(clap::Subcommand, Debug, Clone)]
pub enum TrialsCommand {
    /// Merges the `--json` outputs of `trials --shard K/N` runs into the report one run of the
    /// whole job list gives (the same lines, bit for bit, with `--json`).
    Merge(MergeArgs),
}

#[derive(clap::Args, Debug, Clone)]
pub struct MergeArgs {
    /// The shards' `--json` outputs.
    #[arg(required = true)]
    pub files: Vec<std::path::PathBuf>,
    /// JSON lines (as `trials --json`); otherwise the table.
    #[arg(long)]
    pub json: bool,
}

/// One approach flown by one rule, as `--json` writes it and `trials merge` reads it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct ApproachRecord {
    /// The job's place in the whole job list (sea states x seeds x headings x approaches).
    job: usize,
    sea_state: u32,
    seed: u64,
    /// None with a motion file.
    heading_deg: Option<f64>,
    index: u32,
    rule: String,
    outcome: ApproachOutcome,
}

/// `--shard K/N`: (K - 1, N), checked.
fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("--shard `{s}`: must be K/N with 1 <= K <= N (e.g. 2/8)");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (k, n): (usize, usize) = (
        k.trim().parse().map_err(|_| bad())?,
        n.trim().parse().map_err(|_| bad())?,
    );
    if n == 0 || k == 0 || k > n {
        return Err(bad());
    }
    Ok((k - 1, n))
}

/// The rules an approach can be flown by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Rule {
    Deckwatch,
    Naive,
    Oracle,
}

deckwatch_common::named_enum!(Rule, [Deckwatch => "deckwatch", Naive => "naive", Oracle => "oracle"]);

impl Rule {
    /// A rule as `--rules` and a shard's records name it.
    fn of(name: &str) -> Result<Self, String> {
        Self::parse(name).map_err(|e| format!("--rules: {e}"))
    }

    /// The rule a pipeline flies; None for the oracle, which needs no frames.
    fn flown(self) -> Option<PipelineRule> {
        match self {
            Self::Deckwatch => Some(PipelineRule::Deckwatch),
            Self::Naive => Some(PipelineRule::Naive),
            Self::Oracle => None,
        }
    }
}

mod log;
mod processes;
mod report;

pub use report::merge;
use report::{report, rule_order};

use log::{verdict_markdown, TrialLog};

/// The sea states (and headings) the jobs run over: `--sea-states` and `--headings-deg`, or
/// with a motion file one "sea" 0 at no heading.
fn seas(a: &TrialsArgs) -> (Vec<u32>, Vec<f64>) {
    if a.motion_csv.is_some() {
        (vec![0], vec![f64::NAN])
    } else {
        (a.sea_states.clone(), a.headings_deg.clone())
    }
}

/// The stage chain as the pipeline an approach is flown through, on the approach's simulated
/// clock; the first approach's frames and events go to the rerun log.
struct ChainPipeline<'a> {
    chain: StageChain,
    clock: SimulatedClock,
    log: Option<&'a mut TrialLog>,
    /// The vehicle's flight path and the approach's world: the vehicle's height over the deck,
    /// for the log.
    path: SharedFlightPath,
    world: &'a ApproachWorld,
}

impl ClosedLoopPipeline for ChainPipeline<'_> {
    fn observe_vehicle(&mut self, sample: &VehicleSample) {
        self.chain.vehicle_sample(sample);
    }

    fn next_frame(&mut self, t_s: f64, inject: &mut dyn FnMut(&mut [u8]) -> bool) -> FrameStep {
        match self
            .chain
            .next_frame(Some(self.clock), |_, pixels| inject(pixels))
        {
            None => FrameStep::SourceEnded,
            Some(Err(_)) => FrameStep::Failed, // counted by the chain
            Some(Ok(None)) => FrameStep::Lost,
            Some(Ok(Some(o))) => {
                if let Some(log) = self.log.as_deref_mut() {
                    let over_deck_m = self
                        .path
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .over_deck_m(t_s, self.world.truth(t_s)[2]);
                    log.frame(&o, self.chain.pixels(), over_deck_m);
                }
                FrameStep::Decided(Box::new(o.decision))
            }
        }
    }

    fn watchdog(&mut self, now_ns: u64) -> Option<LandingDecision> {
        self.chain.watchdog(now_ns)
    }

    fn watchdog_period_s(&self) -> f64 {
        self.chain.watchdog_period_s()
    }

    fn note(&mut self, time_ns: u64, text: &str) {
        if let Some(log) = self.log.as_deref() {
            log.text(time_ns, text.to_string());
        }
    }
}

/// Flies one approach through the stage chain: `Deckwatch` acts on the decisions, `Naive` on
/// the attitudes.
fn fly(
    rule: PipelineRule,
    world: &ApproachWorld,
    pipeline: &PipelineConfig,
    model: &ApproachModel,
    a: &TrialsArgs,
    seed: u64,
    log: Option<&mut TrialLog>,
) -> Result<ApproachOutcome, String> {
    let timing = timing(a);
    let mut faults = FrameFaults::new(&fault_model(a), a.rate, seed);
    fly_approach(
        rule,
        world,
        &pipeline.decide,
        model,
        timing,
        &mut faults,
        |scene| {
            let path = scene.path.clone();
            let source = pipeline
                .capture()
                .open_sim_with(Box::new(scene))
                .map_err(|e| e.to_string())?;
            Ok::<_, String>(ChainPipeline {
                chain: StageChain::with_source(pipeline, source).map_err(|e| e.to_string())?,
                clock: SimulatedClock {
                    epoch_ns: deckwatch_trials::fly::EPOCH_NS,
                    stage_latency_ns: timing.stage_latency_ns,
                },
                log,
                path,
                world,
            })
        },
    )
}

/// The approach's clock from the options.
fn timing(a: &TrialsArgs) -> ApproachTiming {
    ApproachTiming {
        rate_hz: a.rate,
        stage_latency_ns: (a.stage_latency_ms * 1e6) as u64,
        watch_before_s: a.watch_before_s,
    }
}

/// The frame faults the options ask for.
fn fault_model(a: &TrialsArgs) -> FrameFaultModel {
    FrameFaultModel {
        drop_share: a.drop_share,
        frozen_per_min: a.frozen_per_min,
        frozen_s: a.frozen_s,
        vehicle_outages_per_min: a.vehicle_outages_per_min,
        vehicle_outage_s: a.vehicle_outage_s,
        vehicle_height_noise_m: a.vehicle_height_noise_m,
        vehicle_height_drift_mps: a.vehicle_height_drift_mps,
    }
}

/// The world of one approach, on the motion file when one is given.
fn world_of(
    job: Approach,
    a: &TrialsArgs,
    recorded: Option<&Arc<RecordedShipMotion>>,
) -> Result<ApproachWorld, String> {
    ApproachWorld::watched(job, recorded, a.sway, a.max_approach_s, a.watch_before_s).map_err(|e| {
        match (e, &a.motion_csv) {
            (e @ WorldError::MotionTooShort { .. }, Some(path)) => {
                format!("--motion-csv: {}: {e}", path.display())
            }
            (e, _) => format!("--sea-states: {e}"),
        }
    })
}

/// The pipeline the trials run: the configuration's stages on the simulator at the trial's
/// rate and image size, compensating with the autopilot's attitude stream.
fn trial_pipeline(a: &TrialsArgs) -> Result<PipelineConfig, String> {
    let (mut p, file) = crate::pipeline::load(a.config.as_deref())?;
    p.source.kind = FrameSource::Simulator;
    p.sim.rate = a.rate;
    p.sim.frames = ((a.watch_before_s + a.max_approach_s) * a.rate).ceil() as usize + 10;
    p.image.width = Some(a.width);
    p.image.height = Some(a.height);
    if a.glints > 0 {
        p.image.glints = Some(a.glints);
    }
    p.vehicle.attitude = VehicleAttitudeSource::Autopilot;
    p.rerun.sink = deckwatch_viz::RerunSink::Off;
    p.decide
        .validate()
        .map_err(|e| ConfigError::in_section(&file, "decide", e).to_string())?;
    Ok(p)
}

/// Everything every approach shares.
struct Setup {
    rules: Vec<Rule>,
    pipeline: PipelineConfig,
    model: ApproachModel,
    /// `--motion-csv`, read once.
    recorded: Option<Arc<RecordedShipMotion>>,
}

/// The first approach (the one logged).
/// Every approach of the run, in the order `job` numbers them.
fn job_list(a: &TrialsArgs) -> Vec<Approach> {
    let mut jobs = Vec::new();
    let (sea_states, headings) = seas(a);
    for &sea_state in &sea_states {
        for &seed in &a.seeds {
            for &heading_deg in &headings {
                for index in 0..a.approaches {
                    jobs.push(Approach {
                        sea_state,
                        seed,
                        heading_deg,
                        index,
                    });
                }
            }
        }
    }
    jobs
}

/// An approach flown by every rule.
type JobResult = Result<Vec<(Rule, ApproachOutcome)>, String>;

/// Flies one approach by every rule.
fn fly_job(job: Approach, setup: &Setup, a: &TrialsArgs, log: Option<&mut Option<TrialLog>>) -> JobResult {
    let world = world_of(job, a, setup.recorded.as_ref())?;
    let approach_seed = job.approach_seed();
    let capacity = &setup.pipeline.decide;
    let model = &setup.model;
    let mut log = log;
    let mut out = Vec::with_capacity(setup.rules.len());
    for &rule in &setup.rules {
        let o = match rule.flown() {
            None => oracle_approach(
                &|t| world.truth(t),
                &|t| world.attitudes(t),
                capacity,
                model,
                1.0 / a.rate,
                3.0 * a.stage_latency_ms / 1e3,
            ),
            Some(flown) => {
                let logged = match (rule, log.as_deref_mut()) {
                    (Rule::Deckwatch, Some(l)) => l.as_mut(),
                    _ => None,
                };
                let o = fly(flown, &world, &setup.pipeline, model, a, approach_seed, logged)?;
                if rule == Rule::Deckwatch {
                    if let Some(l) = log.as_deref_mut().and_then(Option::take) {
                        let at = o.touchdown.as_ref().map_or(model.max_approach_s, |v| v.t_s);
                        l.finish(
                            1_000_000_000 + (at * 1e9) as u64,
                            verdict_markdown(&o, model, capacity),
                        )?;
                    }
                }
                o
            }
        };
        out.push((rule, o));
    }
    Ok(out)
}

pub fn run(a: TrialsArgs) -> Result<(), String> {
    let rules: Vec<Rule> = a.rules.iter().map(|r| Rule::of(r)).collect::<Result<_, _>>()?;
    fault_model(&a).validate().map_err(|e| e.to_string())?;
    let shares_ok = a.sway >= 0.0 && a.rate > 0.0 && a.stage_latency_ms >= 0.0 && a.threads > 0;
    if !shares_ok {
        return Err("--sway, --stage-latency-ms must not be negative, --rate and --threads positive".into());
    }
    // An hour's watch is far beyond the decider's fit window; more only costs frames.
    if !(0.0..=3600.0).contains(&a.watch_before_s) {
        return Err(format!("--watch-before-s {}: must be 0-3600 s", a.watch_before_s));
    }
    if a.watch_before_s > 0.0 && a.processes > 0 {
        return Err("--watch-before-s: the approaches through the processes (--processes) start on arrival; fly them without it".into());
    }
    for &ss in seas(&a).0.iter().filter(|&&ss| ss != 0) {
        if SpectrumShipMotion::sea_state(ss, 1).is_none() {
            return Err(format!("--sea-states: {ss} has no spectrum sea (3, 4, 5, 6)"));
        }
    }
    let recorded = match &a.motion_csv {
        Some(path) => Some(Arc::new(
            RecordedShipMotion::load(path).map_err(|e| format!("--motion-csv: {e}"))?,
        )),
        None => None,
    };
    let jobs = job_list(&a);
    if let Some(&job) = jobs.first() {
        // A motion file that cannot be used says so before any flight.
        world_of(job, &a, recorded.as_ref())?;
    }
    let pipeline = trial_pipeline(&a)?;
    let capacity = pipeline.decide.clone();
    let model = ApproachModel {
        hover_m: a.hover_m,
        wait_clearance_m: a.wait_clearance_m,
        follow_deck: !a.hold_height,
        follow_lag_s: a.follow_lag_s,
        max_approach_s: a.max_approach_s,
        ..ApproachModel::quadrotor(capacity.touchdown_s)
    };
    model.validate()?;
    if a.rrd.is_some() && a.rrd_job >= jobs.len().max(1) {
        return Err(format!(
            "--rrd-job {}: the run has {} approaches",
            a.rrd_job,
            jobs.len()
        ));
    }
    let log = match (&a.rrd, jobs.get(a.rrd_job)) {
        (Some(p), Some(&job)) => Some(TrialLog::start(
            p,
            &capacity,
            format!(
                "deckwatch trial: sea state {}, seed {}, waves {} deg off the bow, approach {}",
                job.sea_state, job.seed, job.heading_deg, job.index
            ),
        )?),
        _ => None,
    };
    if !a.json {
        outln!(
            "closed-loop trials: {} approaches per sea state, seed and heading ({} x {} x {:?} deg); {}x{} at {} Hz, waiting {}, touchdown {} s, sway x{}, ride-through {} ms, no return {} ms (the vehicle's: {} s + descent speed / (2 x {} m/s^2)); faults: drops {}, glints {}, frozen {}/min of {} s, vehicle stream outages {}/min of {} s, height error {} m + drift {} m/s",
            a.approaches, a.seeds.len(), a.headings_deg.len(), a.headings_deg, a.width, a.height, a.rate, if model.follow_deck { format!("{} m over the deck, lagging it by {} s", model.hover_m, model.follow_lag_s) } else { format!("{} m over the mean deck, {} m over its highest", model.hover_m, model.wait_clearance_m) },
            model.touchdown_s, a.sway, capacity.ride_through_ms, capacity.no_return_ms, model.go_around_reaction_s, model.go_around_accel_mps2, a.drop_share, a.glints, a.frozen_per_min, a.frozen_s, a.vehicle_outages_per_min, a.vehicle_outage_s, a.vehicle_height_noise_m, a.vehicle_height_drift_mps
        );
        outln!(
            "{:<4} {:<10} {:>10} {:>8} {:>10} {:>7} {:>7} {:>9} {:>9} {:>9}",
            "sea",
            "rule",
            "approaches",
            "commits",
            "touchdowns",
            "UNSAFE",
            "aborts",
            "abort/cmt",
            "no land",
            "median s"
        );
    }
    // This shard's jobs (all without `--shard`), by their place in the whole list.
    let (part, parts) = match &a.shard {
        Some(s) => parse_shard(s)?,
        None => (0, 1),
    };
    let mine: Vec<(usize, Approach)> = jobs
        .iter()
        .copied()
        .enumerate()
        .filter(|(i, _)| i % parts == part)
        .collect();
    let setup = Setup {
        rules,
        pipeline,
        model,
        recorded,
    };
    let clock = Instant::now();
    // Approaches are independent: as many at once as there are cores (each its own chain).
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: Mutex<Vec<Option<JobResult>>> = Mutex::new(vec![None; mine.len()]);
    let log = Mutex::new(log);
    std::thread::scope(|scope| {
        for _ in 0..a.threads.min(mine.len().max(1)) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&(number, job)) = mine.get(i) else { break };
                // The approach `--rrd-job` names in the whole list is the one logged.
                let r = if number == a.rrd_job {
                    let mut guard = log.lock().unwrap_or_else(|e| e.into_inner());
                    fly_job(job, &setup, &a, Some(&mut guard))
                } else {
                    fly_job(job, &setup, &a, None)
                };
                let failed = r.is_err();
                results.lock().unwrap_or_else(|e| e.into_inner())[i] = Some(r);
                if failed {
                    next.store(mine.len(), std::sync::atomic::Ordering::Relaxed);
                }
            });
        }
    });
    let results = results.into_inner().unwrap_or_else(|e| e.into_inner());
    let mut records = Vec::new();
    for (&(number, job), r) in mine.iter().zip(results) {
        let Some(r) = r else { continue };
        for (rule, outcome) in r? {
            records.push(ApproachRecord {
                job: number,
                sea_state: job.sea_state,
                seed: job.seed,
                heading_deg: Some(job.heading_deg).filter(|h| h.is_finite()),
                index: job.index,
                rule: rule.name().to_string(),
                outcome,
            });
        }
    }
    // Within a job, the rules in one order whatever `--rules` said: a merge sorts them so too.
    records.sort_by(|x, y| {
        x.job
            .cmp(&y.job)
            .then_with(|| rule_order(&x.rule).cmp(&rule_order(&y.rule)))
    });
    let totals = report(&records, a.json)?;
    if a.processes > 0 {
        agreement(&jobs[..a.processes.min(jobs.len())], &setup, &a)?;
    }
    if !a.json {
        let frames: u64 = totals
            .iter()
            .filter(|(r, _)| **r != Rule::Oracle)
            .map(|(_, s)| s.frames)
            .sum();
        outln!(
            "{} frames through the chain in {:.1} s on {} threads",
            frames,
            clock.elapsed().as_secs_f64(),
            a.threads
        );
    }
    Ok(())
}

/// The same approaches in one process (simulated clock) and through the processes (real time).
fn agreement(jobs: &[Approach], setup: &Setup, a: &TrialsArgs) -> Result<(), String> {
    let brief = |o: &ApproachOutcome| match &o.touchdown {
        Some(v) => format!(
            "{} commits, {} go-arounds, touchdown at {:.1} s {}",
            o.commits,
            o.go_arounds,
            v.t_s,
            if v.safe() { "safe" } else { "UNSAFE" }
        ),
        None => format!("{} commits, {} go-arounds, no touchdown", o.commits, o.go_arounds),
    };
    if !a.json {
        outln!("the same approaches through the processes at real time (detect, estimate, decide, link; MAVLink on UDP):");
    }
    for &job in jobs {
        let world = world_of(job, a, setup.recorded.as_ref())?;
        let inproc = fly(
            PipelineRule::Deckwatch,
            &world,
            &setup.pipeline,
            &setup.model,
            a,
            job.approach_seed(),
            None,
        )?;
        let live = processes::fly(job, setup, a)?;
        if a.json {
            outln!(
                "{}",
                serde_json::json!({"agreement": {"sea_state": job.sea_state, "seed": job.seed, "heading_deg": job.heading_deg,
                    "approach": job.index, "in_process": inproc, "processes": live}})
            );
        } else {
            outln!(
                "  sea {} seed {} heading {} #{}: in one process {}; processes {}",
                job.sea_state,
                job.seed,
                job.heading_deg,
                job.index,
                brief(&inproc),
                brief(&live)
            );
        }
    }
    Ok(())
}

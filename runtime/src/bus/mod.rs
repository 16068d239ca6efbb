//! The pipeline's transport: iceoryx2 services, defined once so that every process opens them
//! with the same settings.
//!
//! Each message kind is a publish-subscribe service plus an event service of the same name: the
//! publisher sends the sample, then notifies, and the subscriber sleeps in a `WaitSet` on the
//! listener until then (no polling; an idle stage uses no CPU). Frames are `[u8]` samples with a
//! [`FrameHeader`] user header: capture writes the pixels once into the loaned shared memory and
//! detect reads them in place.
//!
//! Slow consumers never block capture: every service has safe overflow (a full subscriber queue
//! loses its oldest sample, `send` never waits); stages take the newest input and count the
//! sequence gaps as drops.
//!
//! Every message is checked as it is received ([`WireCheck`]: each enum and boolean holds one of
//! its values); one that does not is counted in the subscriber's [`Rejections`] and skipped,
//! never read, since the bytes come from another process.
//!
//! A *domain* isolates pipelines on one machine (tests run several at once): it prefixes every
//! iceoryx2 file in `/dev/shm` and in the iceoryx2 root, a folder of this user's alone
//! ([`ipc_root`]; not iceoryx2's shared `/tmp/iceoryx2`).

use deckwatch_common::messages::{
    monotonic_ns, AttitudeMessage, Channel, FrameHeader, LandingDecision, LinkTraffic, MarkerMessage,
    StageHeartbeat, StageLog, VehicleSample,
};
use deckwatch_common::wire::{BadWireValue, WireCheck};
use deckwatch_common::InvalidField;
use iceoryx2::config::Config;
use iceoryx2::node::{NodeState, NodeView, NodeWaitFailure};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::{
    ipc, AllocationStrategy, CallbackProgression, EventId, FileName, LogLevel, Node, NodeBuilder, NodeName,
    PortFactory, SemanticString, ServiceName, WaitSetBuilder, ZeroCopySend,
};
use iceoryx2::sample::Sample;
use iceoryx2::waitset::WaitSetRunResult;
use std::cell::{Cell, RefCell};
use std::fmt::Debug;
use std::time::Duration;

mod event_loop;
mod frames;
mod root;

pub use event_loop::{event_loop, Flow, LoopEnd, Wake};
pub use frames::{FramePublisher, FrameSample, FrameSubscriber, PublishError, Rejections};
pub use root::{ipc_root, ipc_root_path, runtime_base, SHARED_MEMORY_DIR};

/// What a stage sleeps on: notified when its input has something new.
pub type Listener = iceoryx2::port::listener::Listener<ipc::Service>;

/// The default domain.
pub const DEFAULT_DOMAIN: &str = "deckwatch";

/// `[bus]` of the pipeline configuration.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(default, deny_unknown_fields)]
pub struct BusConfig {
    /// Isolates one pipeline's shared memory from another's on the same machine.
    pub domain: String,
    /// Subscribers the frame service accepts.
    pub frame_subscribers: usize,
    /// Frames queued per subscriber before the oldest is dropped.
    pub frame_queue: usize,
}

impl Default for BusConfig {
    fn default() -> Self {
        Self {
            domain: DEFAULT_DOMAIN.into(),
            frame_subscribers: 2,
            frame_queue: 2,
        }
    }
}

impl BusConfig {
    /// The settings for frames of up to `max_frame_bytes`.
    pub fn settings(&self, max_frame_bytes: usize) -> BusSettings {
        BusSettings {
            domain: self.domain.clone(),
            max_frame_bytes,
            frame_subscribers: self.frame_subscribers,
            frame_queue: self.frame_queue,
        }
    }
}

/// A transport failure, with what was being done.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BusError {
    /// An iceoryx2 call failed.
    #[error("iceoryx2: {what}: {detail}")]
    Iceoryx2 { what: String, detail: String },
    /// Settings that no pipeline can run with (the key and the problem).
    #[error("bus.{}: {}", .0.field, .0.problem)]
    Settings(InvalidField),
    #[error("unknown service `{0}`")]
    UnknownService(String),
}

fn context<E: Debug>(what: impl std::fmt::Display) -> impl FnOnce(E) -> BusError {
    move |e| BusError::Iceoryx2 {
        what: what.to_string(),
        detail: format!("{e:?}"),
    }
}

/// Sizes of the shared-memory services (all processes of a domain must agree).
#[derive(Debug, Clone, PartialEq)]
pub struct BusSettings {
    /// Isolates this pipeline's iceoryx2 resources: `[a-z0-9_-]`, 1..=32 characters.
    pub domain: String,
    /// Largest frame in bytes (stride x height); shared memory holds a few frames of this size.
    pub max_frame_bytes: usize,
    /// Subscribers the frame service accepts (detect, plus observers and a restarted stage
    /// before the dead one is cleaned up).
    pub frame_subscribers: usize,
    /// Frames queued per subscriber before the oldest is dropped.
    pub frame_queue: usize,
}

impl BusSettings {
    pub fn validate(&self) -> Result<(), InvalidField> {
        validate_domain(&self.domain)?;
        if self.max_frame_bytes == 0 {
            return Err(InvalidField::new("max_frame_bytes", "must be positive"));
        }
        if !(1..=8).contains(&self.frame_subscribers) {
            return Err(InvalidField::new(
                "frame_subscribers",
                format!("must be 1..=8, got {}", self.frame_subscribers),
            ));
        }
        if !(1..=16).contains(&self.frame_queue) {
            return Err(InvalidField::new(
                "frame_queue",
                format!("must be 1..=16, got {}", self.frame_queue),
            ));
        }
        Ok(())
    }

    /// Shared memory the frame service reserves: samples for every subscriber's queue and
    /// borrows, plus the publisher's loans.
    pub fn frame_memory_bytes(&self) -> usize {
        let samples = self.frame_subscribers * (self.frame_queue + FRAME_BORROWS) + FRAME_LOANS;
        samples * self.max_frame_bytes
    }

    /// The iceoryx2 file-name prefix of this domain.
    pub fn prefix(&self) -> String {
        domain_prefix(&self.domain)
    }
}

/// Checks a domain name; the error says what is allowed.
pub fn validate_domain(domain: &str) -> Result<(), InvalidField> {
    let ok = !domain.is_empty()
        && domain.len() <= 32
        && domain
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_' || b == b'-');
    if ok {
        Ok(())
    } else {
        Err(InvalidField::new(
            "domain",
            format!("`{domain}` must be 1..=32 characters of a-z, 0-9, _ and -"),
        ))
    }
}

/// The iceoryx2 file-name prefix of a domain: every shared-memory and state file of the domain
/// starts with it.
pub fn domain_prefix(domain: &str) -> String {
    format!("iox2_dw_{domain}_")
}

// A stage holds its newest frame while receiving the next one.
const FRAME_BORROWS: usize = 2;
// Capture fills one frame at a time.
const FRAME_LOANS: usize = 1;
// Small messages: deep enough that a burst is not lost while a stage is busy.
const MESSAGE_QUEUE: usize = 8;
const MESSAGE_SUBSCRIBERS: usize = 8;

// How long a stage keeps retrying to open a service that another stage is still creating.
// iceoryx2's default (1 s) is too short when all stages start at once on a loaded 2-core
// machine: a CI run saw the recorder give up with `SystemInFlux` while the creator was
// descheduled. Waiting longer costs nothing when the service is ready.
const SERVICE_CREATION_TIMEOUT: Duration = Duration::from_secs(10);

fn domain_config(domain: &str) -> Result<Config, BusError> {
    validate_domain(domain).map_err(BusError::Settings)?;
    let mut config = Config::default();
    config.global.prefix =
        FileName::new(domain_prefix(domain).as_bytes()).map_err(context("domain prefix"))?;
    config.global.creation_timeout = SERVICE_CREATION_TIMEOUT;
    let root = ipc_root(domain)?;
    // iceoryx2's paths are folders with a trailing separator (its own default: `/tmp/iceoryx2/`).
    let root = format!("{}/", root.display());
    config
        .global
        .set_root_path(&iceoryx2::prelude::Path::new(root.as_bytes()).map_err(context("iceoryx2 root"))?);
    Ok(config)
}

/// Silences iceoryx2's info/warn output (e.g. "no config file loaded"); call before joining.
pub fn quiet_logging() {
    iceoryx2::prelude::set_log_level_from_env_or(LogLevel::Error);
}

/// What [`Bus::cleanup_dead_nodes`] removed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CleanupReport {
    pub removed: u64,
    pub failed: u64,
}

// The frame header is read in place out of shared memory too.
const _: () = {
    const fn any_bit_pattern<T: bytemuck::AnyBitPattern>() {}
    any_bit_pattern::<FrameHeader>();
};

/// One process's connection to a domain: an iceoryx2 node.
pub struct Bus {
    node: Node<ipc::Service>,
    settings: BusSettings,
}

/// A small fixed-size message published on its own service (its [`Channel`]'s). Any bytes are a value of it
/// (`AnyBitPattern`: its enums and booleans are `WireCode`s and `WireBool`s), so reading what
/// another process wrote is never undefined behaviour; `WireCheck` then says whether they are
/// values of their types.
pub trait Message:
    Channel + Debug + Copy + Default + ZeroCopySend + WireCheck + bytemuck::AnyBitPattern + 'static
{
    /// Messages queued per subscriber before the oldest is dropped.
    const QUEUE: usize = MESSAGE_QUEUE;
    /// Publishers the service accepts.
    const PUBLISHERS: usize = 2;
}

impl Message for MarkerMessage {}
impl Message for AttitudeMessage {}
impl Message for LandingDecision {}
impl Message for StageHeartbeat {
    // Six processes at 10 Hz, read by the launcher every 50 ms.
    const QUEUE: usize = 64;
    // Every stage process, and the one a restart starts while the old one is being removed.
    const PUBLISHERS: usize = 12;
}
impl Message for StageLog {
    // A burst of lines (a stage's summary, a restart) while the recorder writes a frame.
    const QUEUE: usize = 64;
}
impl Message for LinkTraffic {
    // The autopilot's streams (attitude at 200 Hz, heartbeats, positions) in and the decisions
    // out: half a second of them.
    const QUEUE: usize = 256;
}
impl Message for VehicleSample {
    // 200 Hz: 320 ms of samples, so a frame's mid-exposure stays bracketed while estimate is busy.
    const QUEUE: usize = 64;
}

type PubSub<P, H> = iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, P, H>;
type EventService = iceoryx2::service::port_factory::event::PortFactory<ipc::Service>;

impl Bus {
    /// Joins the domain as a node called `name`; removes what dead nodes of the domain left.
    pub fn join(settings: &BusSettings, name: &str) -> Result<Self, BusError> {
        settings.validate().map_err(BusError::Settings)?;
        let config = domain_config(&settings.domain)?;
        let node_name = NodeName::new(name).map_err(context(format!("node name `{name}`")))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&config)
            .create::<ipc::Service>()
            .map_err(context(format!("creating node `{name}`")))?;
        root::close_shared_counters(&settings.domain)?;
        Ok(Self {
            node,
            settings: settings.clone(),
        })
    }

    pub fn settings(&self) -> &BusSettings {
        &self.settings
    }

    /// Removes the shared-memory resources of crashed processes of the domain.
    pub fn cleanup_dead_nodes(domain: &str) -> Result<CleanupReport, BusError> {
        let config = domain_config(domain)?;
        let mut report = CleanupReport::default();
        Node::<ipc::Service>::list(&config, |state| {
            if let NodeState::Dead(view) = state {
                match view.try_remove_stale_resources() {
                    Ok(_) => report.removed += 1,
                    Err(_) => report.failed += 1,
                }
            }
            CallbackProgression::Continue
        })
        .map_err(context("listing nodes"))?;
        Ok(report)
    }

    /// Names of the live nodes of the domain.
    pub fn live_nodes(domain: &str) -> Result<Vec<String>, BusError> {
        let config = domain_config(domain)?;
        let mut names = Vec::new();
        Node::<ipc::Service>::list(&config, |state| {
            if let NodeState::Alive(view) = state {
                if let Some(details) = view.details().as_ref() {
                    names.push(details.name().as_str().to_string());
                }
            }
            CallbackProgression::Continue
        })
        .map_err(context("listing nodes"))?;
        Ok(names)
    }

    /// Removes the one file a domain keeps after its last node is gone (iceoryx2's persistent
    /// node counter, the "global management segment"), so that a stopped pipeline leaves
    /// nothing in /dev/shm. Does nothing (returns false) while any node of the domain is alive.
    pub fn remove_idle_domain(domain: &str) -> Result<bool, BusError> {
        Self::cleanup_dead_nodes(domain)?;
        if !Self::live_nodes(domain)?.is_empty() {
            return Ok(false);
        }
        let config = domain_config(domain)?;
        // SAFETY: iceoryx2 requires that no process uses the domain: checked just above (a
        // domain belongs to one launcher, which has stopped its stages).
        unsafe { iceoryx2::testing::remove_global_mgmt_segment::<ipc::Service>(&config) }
            .map_err(context("removing the domain's management segment"))
    }

    fn service_name(name: &str) -> Result<ServiceName, BusError> {
        ServiceName::new(name).map_err(context(format!("service name `{name}`")))
    }

    fn event_service(&self, name: &str) -> Result<EventService, BusError> {
        self.node
            .service_builder(&Self::service_name(name)?)
            .event()
            .open_or_create()
            .map_err(context(format!("event service `{name}`")))
    }

    fn frame_service(&self) -> Result<PubSub<[u8], FrameHeader>, BusError> {
        let s = &self.settings;
        self.node
            .service_builder(&Self::service_name(FrameHeader::SERVICE)?)
            .publish_subscribe::<[u8]>()
            .user_header::<FrameHeader>()
            .max_publishers(2)
            .max_subscribers(s.frame_subscribers)
            .subscriber_max_buffer_size(s.frame_queue)
            .subscriber_max_borrowed_samples(FRAME_BORROWS)
            .history_size(0)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(context(format!("service `{}`", FrameHeader::SERVICE)))
    }

    fn message_service<M: Message>(&self) -> Result<PubSub<M, ()>, BusError> {
        self.node
            .service_builder(&Self::service_name(M::SERVICE)?)
            .publish_subscribe::<M>()
            .max_publishers(M::PUBLISHERS)
            .max_subscribers(MESSAGE_SUBSCRIBERS)
            .subscriber_max_buffer_size(M::QUEUE)
            .subscriber_max_borrowed_samples(2)
            .history_size(0)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(context(format!("service `{}`", M::SERVICE)))
    }

    /// Capture's end of the frame service.
    pub fn frame_publisher(&self) -> Result<FramePublisher, BusError> {
        let service = self.frame_service()?;
        let publisher = service
            .publisher_builder()
            .initial_max_slice_len(self.settings.max_frame_bytes)
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_samples(FRAME_LOANS)
            .create()
            .map_err(context("frame publisher"))?;
        let notifier = self
            .event_service(FrameHeader::SERVICE)?
            .notifier_builder()
            .default_event_id(EventId::new(0))
            .create()
            .map_err(context("frame notifier"))?;
        Ok(FramePublisher {
            publisher,
            notifier,
            max_bytes: self.settings.max_frame_bytes,
        })
    }

    /// A frame consumer (detect, observers).
    pub fn frame_subscriber(&self) -> Result<FrameSubscriber, BusError> {
        let service = self.frame_service()?;
        let subscriber = service
            .subscriber_builder()
            .buffer_size(self.settings.frame_queue)
            .create()
            .map_err(context("frame subscriber"))?;
        let listener = self
            .event_service(FrameHeader::SERVICE)?
            .listener_builder()
            .create()
            .map_err(context("frame listener"))?;
        Ok(FrameSubscriber {
            subscriber,
            listener,
            rejections: Rejections::new(FrameHeader::SERVICE),
            _service: service,
        })
    }

    pub fn publisher<M: Message>(&self) -> Result<MessagePublisher<M>, BusError> {
        let publisher = self
            .message_service::<M>()?
            .publisher_builder()
            .max_loaned_samples(1)
            .create()
            .map_err(context(format!("publisher of `{}`", M::SERVICE)))?;
        let notifier = self
            .event_service(M::SERVICE)?
            .notifier_builder()
            .default_event_id(EventId::new(0))
            .create()
            .map_err(context(format!("notifier of `{}`", M::SERVICE)))?;
        Ok(MessagePublisher { publisher, notifier })
    }

    pub fn subscriber<M: Message>(&self) -> Result<MessageSubscriber<M>, BusError> {
        let service = self.message_service::<M>()?;
        let subscriber = service
            .subscriber_builder()
            .buffer_size(M::QUEUE)
            .create()
            .map_err(context(format!("subscriber of `{}`", M::SERVICE)))?;
        let listener = self
            .event_service(M::SERVICE)?
            .listener_builder()
            .create()
            .map_err(context(format!("listener of `{}`", M::SERVICE)))?;
        Ok(MessageSubscriber {
            subscriber,
            listener,
            rejections: Rejections::new(M::SERVICE),
            service,
        })
    }

    /// Number of subscribers currently connected to a service (the launcher's readiness check).
    pub fn subscriber_count(&self, service: &str) -> Result<usize, BusError> {
        Ok(match service {
            s if s == FrameHeader::SERVICE => self.frame_service()?.dynamic_config().number_of_subscribers(),
            s if s == MarkerMessage::SERVICE => self
                .message_service::<MarkerMessage>()?
                .dynamic_config()
                .number_of_subscribers(),
            s if s == AttitudeMessage::SERVICE => self
                .message_service::<AttitudeMessage>()?
                .dynamic_config()
                .number_of_subscribers(),
            s if s == LandingDecision::SERVICE => self
                .message_service::<LandingDecision>()?
                .dynamic_config()
                .number_of_subscribers(),
            other => return Err(BusError::UnknownService(other.to_string())),
        })
    }

    /// Sleeps up to `timeout`; `false` when a termination signal (SIGINT, SIGTERM) arrived.
    pub fn sleep(&self, timeout: Duration) -> bool {
        match self.node.wait(timeout) {
            Ok(()) => true,
            // Any signal cuts the sleep short (SIGCONT after a SIGSTOP, SIGWINCH): only SIGINT
            // and SIGTERM, which iceoryx2's handler recorded, mean stop.
            Err(NodeWaitFailure::Interrupt) => self.node.wait(Duration::ZERO).is_ok(),
            Err(_) => false,
        }
    }
}

/// A publisher of one message kind.
pub struct MessagePublisher<M: Message> {
    publisher: Publisher<ipc::Service, M, ()>,
    notifier: Notifier<ipc::Service>,
}

impl<M: Message> MessagePublisher<M> {
    /// Sends a copy of `message` and wakes the subscribers; the number reached.
    pub fn send(&self, message: &M) -> Result<usize, BusError> {
        let sample = self
            .publisher
            .loan_uninit()
            .map_err(|e| context(format!("loan on `{}`", M::SERVICE))(e))?;
        let delivered = sample
            .write_payload(*message)
            .send()
            .map_err(|e| context(format!("send on `{}`", M::SERVICE))(e))?;
        let _ = self.notifier.notify();
        Ok(delivered)
    }
}

/// A subscriber of one message kind.
pub struct MessageSubscriber<M: Message> {
    subscriber: Subscriber<ipc::Service, M, ()>,
    listener: Listener,
    rejections: Rejections,
    service: PubSub<M, ()>,
}

impl<M: Message> MessageSubscriber<M> {
    pub fn listener(&self) -> &Listener {
        &self.listener
    }

    /// The next queued message whose every enum and boolean holds a value, copied out of shared
    /// memory; the ones that do not are skipped and counted in [`Self::rejections`].
    pub fn receive(&self) -> Result<Option<M>, BusError> {
        loop {
            let Some(sample) = self
                .subscriber
                .receive()
                .map_err(|e| context(format!("receive on `{}`", M::SERVICE))(e))?
            else {
                return Ok(None);
            };
            // Checked in place: only a message that passes is copied out and read.
            match sample.payload().check_wire() {
                Ok(()) => return Ok(Some(*sample.payload())),
                Err(e) => self.rejections.reject(e.within(short_type_name::<M>())),
            }
        }
    }

    pub fn rejections(&self) -> &Rejections {
        &self.rejections
    }

    /// Publishers currently connected.
    pub fn publisher_count(&self) -> usize {
        self.service.dynamic_config().number_of_publishers()
    }
}

/// `LandingDecision` for `deckwatch_common::messages::LandingDecision`: the name in errors.
fn short_type_name<T>() -> &'static str {
    let full = std::any::type_name::<T>();
    full.rsplit("::").next().unwrap_or(full)
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::messages::{DecisionState, FrameStamp};
    use deckwatch_common::wire::{WireBool, WireCode};

    #[test]
    fn domains_and_settings_are_checked() {
        assert!(validate_domain("deckwatch").is_ok());
        assert!(validate_domain("a_b-9").is_ok());
        for bad in ["", "Upper", "sp ace", "x/y", &"a".repeat(33)] {
            assert!(validate_domain(bad).is_err(), "{bad}");
        }
        let s = BusConfig::default().settings(100);
        assert!(s.validate().is_ok());
        assert_eq!(s.prefix(), "iox2_dw_deckwatch_");
        // 2 subscribers x (queue 2 + 2 borrowed) + 1 loan = 9 frames.
        assert_eq!(s.frame_memory_bytes(), 900);
        for bad in [
            BusSettings {
                max_frame_bytes: 0,
                ..s.clone()
            },
            BusSettings {
                frame_subscribers: 9,
                ..s.clone()
            },
            BusSettings {
                frame_queue: 0,
                ..s.clone()
            },
        ] {
            assert!(bad.validate().is_err(), "{bad:?}");
        }
        let e = Bus::join(
            &BusSettings {
                domain: "Bad".into(),
                ..s
            },
            "x",
        )
        .err()
        .unwrap();
        assert!(matches!(e, BusError::Settings(_)), "{e}");
    }

    /// A signal that is not a stop request interrupts the wait (as SIGCONT does after a SIGSTOP;
    /// here SIGUSR1 with a handler that does nothing) but ends neither the loop nor a sleep.
    #[test]
    fn other_signals_do_not_stop_the_loop() {
        quiet_logging();
        let domain = format!("unit-sig-{}", std::process::id());
        let settings = BusConfig {
            domain: domain.clone(),
            ..Default::default()
        }
        .settings(64);
        extern "C" fn ignore(_: libc::c_int) {}
        // SAFETY: installs a handler that does nothing (async-signal-safe) for SIGUSR1, which
        // nothing else in this test binary uses.
        unsafe { libc::signal(libc::SIGUSR1, ignore as *const () as libc::sighandler_t) };
        let (tx, rx) = std::sync::mpsc::channel();
        let waiter = std::thread::spawn(move || {
            let bus = Bus::join(&settings, "unit-sig").unwrap();
            let sub = bus.subscriber::<LandingDecision>().unwrap();
            // SAFETY: pthread_self has no preconditions.
            tx.send(unsafe { libc::pthread_self() } as usize).unwrap();
            let mut ticks = 0;
            let end = event_loop(&[sub.listener()], Some(Duration::from_millis(20)), |_| {
                ticks += 1;
                Ok::<_, BusError>(if ticks >= 25 { Flow::Stop } else { Flow::Continue })
            })
            .unwrap();
            let slept = bus.sleep(Duration::from_millis(200));
            (end, slept)
        });
        let thread = rx.recv().unwrap() as libc::pthread_t;
        for _ in 0..30 {
            std::thread::sleep(Duration::from_millis(10));
            // SAFETY: the waiter thread is alive until it has ticked 25 times and slept (it
            // does not end before we stop signalling: 30 x 10 ms < 25 x 20 ms + 200 ms).
            unsafe { libc::pthread_kill(thread, libc::SIGUSR1) };
        }
        assert_eq!(waiter.join().unwrap(), (LoopEnd::Stopped, true));
        Bus::remove_idle_domain(&domain).unwrap();
    }

    /// Stages start at once and race to create the same services: every one of them opens
    /// them (one creates, the others wait for it rather than fail with `SystemInFlux`), and
    /// the domain's settings carry the longer creation timeout.
    #[test]
    fn stages_starting_together_all_open_the_services() {
        quiet_logging();
        let domain = format!("unit-race-{}", std::process::id());
        assert_eq!(
            domain_config(&domain).unwrap().global.creation_timeout,
            SERVICE_CREATION_TIMEOUT
        );
        const STAGES: usize = 6;
        let settings = BusConfig {
            domain: domain.clone(),
            frame_subscribers: STAGES,
            ..Default::default()
        }
        .settings(64);
        // Every stage joins, then all open at once; they stay open until every one has
        // counted the others.
        let start = std::sync::Arc::new(std::sync::Barrier::new(STAGES));
        let opened = std::sync::Arc::new(std::sync::Barrier::new(STAGES));
        let stages: Vec<_> = (0..STAGES)
            .map(|i| {
                let (settings, start, opened) = (settings.clone(), start.clone(), opened.clone());
                std::thread::spawn(move || {
                    let bus = Bus::join(&settings, &format!("race{i}"));
                    start.wait();
                    let ports = bus.and_then(|bus| {
                        let sub = bus.subscriber::<LandingDecision>()?;
                        let frames = bus.frame_subscriber()?;
                        Ok((bus, sub, frames))
                    });
                    opened.wait();
                    let counted = match &ports {
                        Ok((bus, _, _)) => bus.subscriber_count(LandingDecision::SERVICE).ok(),
                        Err(_) => None,
                    };
                    start.wait();
                    ports.map(|_| counted).map_err(|e| e.to_string())
                })
            })
            .collect();
        for (i, stage) in stages.into_iter().enumerate() {
            assert_eq!(stage.join().unwrap(), Ok(Some(STAGES)), "stage {i}");
        }
        Bus::remove_idle_domain(&domain).unwrap();
    }

    /// One process, real shared memory: a message and a frame go through, the frame in place.
    #[test]
    fn messages_and_frames_round_trip() {
        quiet_logging();
        let domain = format!("unit-bus-{}", std::process::id());
        let settings = BusConfig {
            domain: domain.clone(),
            ..Default::default()
        }
        .settings(64);
        {
            let bus = Bus::join(&settings, "unit").unwrap();
            let sub = bus.subscriber::<LandingDecision>().unwrap();
            let publisher = bus.publisher::<LandingDecision>().unwrap();
            assert_eq!(bus.subscriber_count(LandingDecision::SERVICE).unwrap(), 1);
            assert!(bus.subscriber_count("nope").is_err());
            let d = LandingDecision {
                state: DecisionState::Hold.into(),
                ..Default::default()
            };
            assert_eq!(publisher.send(&d).unwrap(), 1);
            assert_eq!(sub.receive().unwrap().unwrap().state, DecisionState::Hold);
            assert!(sub.receive().unwrap().is_none());
            // A bad code and a bad boolean (what a corrupt process could write) are skipped and
            // counted; the good message behind them comes through.
            let bad_state = LandingDecision {
                state: WireCode::from_code(7),
                ..d
            };
            let mut bad_valid = d;
            bad_valid.attitude.valid = WireBool::from_byte(2);
            let good = LandingDecision {
                stamp: FrameStamp {
                    seq: 9,
                    ..Default::default()
                },
                ..d
            };
            for m in [bad_state, bad_valid, good] {
                publisher.send(&m).unwrap();
            }
            assert_eq!(sub.receive().unwrap().unwrap().stamp.seq, 9);
            assert!(sub.receive().unwrap().is_none());
            assert_eq!(sub.rejections().count(), 2);
            let line = sub.rejections().report(1).unwrap();
            assert!(
                line.contains("`LandingDecision.attitude.valid` holds 2, which is no bool")
                    && line.contains("2 skipped so far"),
                "{line}"
            );
            assert!(sub.rejections().report(2).is_none());
            assert_eq!(sub.publisher_count(), 1);

            let frames = bus.frame_subscriber().unwrap();
            let fp = bus.frame_publisher().unwrap();
            let header = FrameHeader {
                width: 8,
                height: 4,
                stride: 8,
                ..Default::default()
            };
            for seq in 0..2u64 {
                let mut h = header;
                h.stamp.seq = seq;
                fp.publish(h, |_, px| {
                    px.fill(seq as u8 + 1);
                    Ok::<(), String>(())
                })
                .unwrap();
            }
            // Latest-frame semantics: the older one is passed over.
            let (frame, passed) = frames.receive_latest().unwrap().unwrap();
            assert_eq!((frame.header().stamp.seq, passed), (1, 1));
            assert!(frame.header().stamp.times.published_ns > 0);
            assert!(frame.pixels()[..32].iter().all(|&b| b == 2));
            drop(frame);
            let too_big = FrameHeader {
                width: 100,
                height: 100,
                stride: 100,
                ..Default::default()
            };
            let e = fp.publish(too_big, |_, _| Ok::<(), String>(())).err().unwrap();
            assert!(matches!(e, PublishError::TooLarge { .. }), "{e}");
            let e = fp.publish(header, |_, _| Err("bad file")).err().unwrap();
            assert!(matches!(e, PublishError::Fill("bad file")));
            // A frame header with a pixel format that is none is released unread.
            let mut bad = header;
            bad.pixel_format = WireCode::from_code(9);
            fp.publish(bad, |_, _| Ok::<(), String>(())).unwrap();
            assert!(frames.receive_latest().unwrap().is_none());
            assert_eq!(frames.rejections().count(), 1);
            let line = frames.rejections().report(1).unwrap();
            assert!(
                line.contains("`FrameHeader.pixel_format` holds 9, which is no PixelFormat"),
                "{line}"
            );
            assert_eq!(Bus::live_nodes(&domain).unwrap(), vec!["unit".to_string()]);
            assert!(!Bus::remove_idle_domain(&domain).unwrap());
        }
        assert!(Bus::live_nodes(&domain).unwrap().is_empty());
        assert!(Bus::remove_idle_domain(&domain).unwrap());
    }
}

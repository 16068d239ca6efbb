//! The frame service: a publisher that lets the source write a frame straight into a loaned
//! shared-memory sample, and a subscriber that reads it in place and checks every header.

use super::*;

/// Why a frame could not be published.
#[derive(Debug)]
pub enum PublishError<E> {
    /// No shared-memory sample was free (every one is queued or held by consumers); the frame
    /// is dropped.
    NoSample(String),
    /// The producer failed to fill the frame; nothing was sent.
    Fill(E),
    /// The frame is larger than the service's frames (`BusSettings::max_frame_bytes`).
    TooLarge {
        bytes: usize,
        max: usize,
    },
    Send(String),
}

impl<E: std::fmt::Display> std::fmt::Display for PublishError<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoSample(e) => write!(f, "no free frame sample in shared memory ({e})"),
            Self::Fill(e) => write!(f, "{e}"),
            Self::TooLarge { bytes, max } => {
                write!(
                    f,
                    "frame of {bytes} bytes exceeds the configured maximum of {max}"
                )
            }
            Self::Send(e) => write!(f, "sending the frame: {e}"),
        }
    }
}

/// Capture's frame publisher.
pub struct FramePublisher {
    pub(super) publisher: Publisher<ipc::Service, [u8], FrameHeader>,
    pub(super) notifier: Notifier<ipc::Service>,
    pub(super) max_bytes: usize,
}

impl FramePublisher {
    /// Loans a shared-memory sample of `header.required_len()` bytes, lets `fill` write the
    /// pixels straight into it (and complete the header), then sends it and wakes the
    /// subscribers. `fill` must write every byte of the slice it gets. Returns the number of
    /// subscribers reached.
    pub fn publish<E>(
        &self,
        mut header: FrameHeader,
        fill: impl FnOnce(&mut FrameHeader, &mut [u8]) -> Result<(), E>,
    ) -> Result<usize, PublishError<E>> {
        let len = header.required_len();
        if len > self.max_bytes {
            return Err(PublishError::TooLarge {
                bytes: len,
                max: self.max_bytes,
            });
        }
        let mut sample = self
            .publisher
            .loan_slice_uninit(len)
            .map_err(|e| PublishError::NoSample(format!("{e:?}")))?;
        let payload = sample.payload_mut();
        // SAFETY: the sample lies in a shared-memory mapping: its bytes are initialised memory
        // (zero-filled by the kernel, then earlier frames), and any byte is a valid u8. The
        // slice does not outlive `sample`, and `fill` overwrites all of it before it is sent.
        let bytes: &mut [u8] =
            unsafe { std::slice::from_raw_parts_mut(payload.as_mut_ptr() as *mut u8, payload.len()) };
        fill(&mut header, bytes).map_err(PublishError::Fill)?;
        header.stamp.times.published_ns = monotonic_ns();
        *sample.user_header_mut() = header;
        // SAFETY: every byte was written by `fill` (see above).
        let sample = unsafe { sample.assume_init() };
        let delivered = sample.send().map_err(|e| PublishError::Send(format!("{e:?}")))?;
        // A failed wake-up is not fatal: the subscriber still gets the frame with the next one.
        let _ = self.notifier.notify();
        Ok(delivered)
    }
}

/// A frame borrowed from shared memory; the pixels stay in place until it is dropped.
pub struct FrameSample {
    pub(super) sample: Sample<ipc::Service, [u8], FrameHeader>,
}

impl FrameSample {
    pub fn header(&self) -> &FrameHeader {
        self.sample.user_header()
    }

    /// The pixel bytes, in shared memory (no copy).
    pub fn pixels(&self) -> &[u8] {
        self.sample.payload()
    }
}

/// Received messages (or frame headers) that were skipped because a field held no value of its
/// type: how many, and what to say about them.
#[derive(Debug)]
pub struct Rejections {
    pub(super) service: &'static str,
    pub(super) count: Cell<u64>,
    /// The newest rejection not yet reported.
    pub(super) unreported: RefCell<Option<BadWireValue>>,
    pub(super) reported_ns: Cell<u64>,
}

impl Rejections {
    /// Reports of further rejections come at most this often (a corrupt publisher must not
    /// flood the log at the frame rate).
    pub const REPORT_INTERVAL_NS: u64 = 5_000_000_000;

    pub(super) fn new(service: &'static str) -> Self {
        Self {
            service,
            count: Cell::new(0),
            unreported: RefCell::new(None),
            reported_ns: Cell::new(0),
        }
    }

    pub(super) fn reject(&self, e: BadWireValue) {
        self.count.set(self.count.get().saturating_add(1));
        *self.unreported.borrow_mut() = Some(e);
    }

    /// Messages skipped so far.
    pub fn count(&self) -> u64 {
        self.count.get()
    }

    /// A line about the newest unreported rejection, when one is due: the first at once, later
    /// ones at most every [`Self::REPORT_INTERVAL_NS`].
    pub fn report(&self, now_ns: u64) -> Option<String> {
        let last = self.reported_ns.get();
        if last != 0 && now_ns.saturating_sub(last) < Self::REPORT_INTERVAL_NS {
            return None;
        }
        let e = self.unreported.borrow_mut().take()?;
        self.reported_ns.set(now_ns.max(1));
        Some(format!(
            "skipped a bad message on `{}`: {e} ({} skipped so far)",
            self.service,
            self.count()
        ))
    }
}

/// A consumer of frames.
pub struct FrameSubscriber {
    pub(super) subscriber: Subscriber<ipc::Service, [u8], FrameHeader>,
    pub(super) listener: Listener,
    pub(super) rejections: Rejections,
    pub(super) _service: PubSub<[u8], FrameHeader>,
}

impl FrameSubscriber {
    pub fn listener(&self) -> &Listener {
        &self.listener
    }

    /// The newest queued frame (older queued frames are released unprocessed: latest-frame
    /// semantics) and how many were passed over. A frame whose header holds a bad enum or
    /// boolean is released unread and counted in [`Self::rejections`].
    pub fn receive_latest(&self) -> Result<Option<(FrameSample, u64)>, BusError> {
        let mut newest = None;
        let mut passed = 0u64;
        while let Some(sample) = self.subscriber.receive().map_err(context("receiving a frame"))? {
            if let Err(e) = sample.user_header().check_wire() {
                self.rejections.reject(e.within("FrameHeader"));
                continue;
            }
            if newest.replace(FrameSample { sample }).is_some() {
                passed += 1;
            }
        }
        Ok(newest.map(|s| (s, passed)))
    }

    /// The oldest queued frame (every frame in order, for a consumer that must see each one:
    /// the recorder); a frame whose header holds a bad enum or boolean is released unread and
    /// counted.
    pub fn receive(&self) -> Result<Option<FrameSample>, BusError> {
        while let Some(sample) = self.subscriber.receive().map_err(context("receiving a frame"))? {
            match sample.user_header().check_wire() {
                Ok(()) => return Ok(Some(FrameSample { sample })),
                Err(e) => self.rejections.reject(e.within("FrameHeader")),
            }
        }
        Ok(None)
    }

    pub fn rejections(&self) -> &Rejections {
        &self.rejections
    }
}

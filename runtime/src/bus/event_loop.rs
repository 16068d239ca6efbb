//! A stage's event loop: sleep until an input is notified or the tick is due, then handle it;
//! ends on SIGINT/SIGTERM or when the handler says so.

use super::*;

/// Why a stage's event loop was woken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wake {
    /// The listener at this index was notified (its events are already consumed).
    Input(usize),
    /// The periodic tick.
    Tick,
}

/// How an event loop ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoopEnd {
    /// SIGINT or SIGTERM.
    Signal,
    /// The handler asked to stop.
    Stopped,
}

/// What the handler wants next.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flow {
    Continue,
    Stop,
}

/// Sleeps until a listener is notified or the tick is due, calls `handler`, repeats; returns on
/// SIGINT/SIGTERM, when the handler says stop, or with the handler's first error.
pub fn event_loop<E>(
    inputs: &[&Listener],
    tick: Option<Duration>,
    mut handler: impl FnMut(Wake) -> Result<Flow, E>,
) -> Result<LoopEnd, E>
where
    E: From<BusError>,
{
    let waitset = WaitSetBuilder::new()
        .create::<ipc::Service>()
        .map_err(|e| E::from(context("creating a waitset")(e)))?;
    let mut guards = Vec::with_capacity(inputs.len());
    for l in inputs {
        guards.push(
            waitset
                .attach_notification(*l)
                .map_err(|e| E::from(context("attaching a listener")(e)))?,
        );
    }
    let tick_guard = match tick {
        Some(t) => Some(
            waitset
                .attach_interval(t)
                .map_err(|e| E::from(context("attaching a tick")(e)))?,
        ),
        None => None,
    };
    let mut failure = None;
    let mut stopped = false;
    let mut on_event = |id: iceoryx2::waitset::WaitSetAttachmentId<ipc::Service>| {
        let mut wakes = Vec::with_capacity(2);
        for (i, g) in guards.iter().enumerate() {
            if id.has_event_from(g) {
                // Consume the notifications, or the waitset fires again at once.
                let _ = inputs[i].try_wait(|_| {});
                wakes.push(Wake::Input(i));
            }
        }
        if tick_guard.as_ref().is_some_and(|g| id.has_event_from(g)) {
            wakes.push(Wake::Tick);
        }
        for w in wakes {
            match handler(w) {
                Ok(Flow::Continue) => {}
                Ok(Flow::Stop) => {
                    stopped = true;
                    return CallbackProgression::Stop;
                }
                Err(e) => {
                    failure = Some(e);
                    return CallbackProgression::Stop;
                }
            }
        }
        CallbackProgression::Continue
    };
    let result = loop {
        match waitset.wait_and_process(&mut on_event) {
            // Any signal interrupts the wait (SIGCONT after a SIGSTOP, too). SIGINT and SIGTERM
            // were recorded by iceoryx2's handler: the next call reports them as a termination
            // request; any other signal is no reason to stop.
            Ok(WaitSetRunResult::Interrupt) => continue,
            other => break other,
        }
    };
    if let Some(e) = failure {
        return Err(e);
    }
    match result {
        Ok(WaitSetRunResult::TerminationRequest) => Ok(LoopEnd::Signal),
        Ok(_) => {
            debug_assert!(stopped);
            Ok(LoopEnd::Stopped)
        }
        Err(e) => Err(E::from(context("waiting")(e))),
    }
}

//! A row of stages: a tuple of [`Stage`]s in pipeline order, the first taking frames in and
//! each later one the output of the one before. The pipeline's row,
//! [`crate::stages::FrameStages`], is declared once: the process table
//! ([`crate::stages::PROCESSES`]) lists its stages, the in-process chain ([`crate::chain`]) runs
//! them one after the other on each frame, and its places are the stage table's
//! ([`PipelineStage`]), checked when it compiles ([`places_follow_the_table`]).

use crate::bus::Message;
use crate::config::{ConfigError, PipelineConfig};
use crate::stage::{process, Frame, Frames, ProcessInfo, Stage};
use deckwatch_common::messages::{
    AttitudeMessage, Channel, FrameStamp, LandingDecision, MarkerMessage, PipelineStage, VehicleSample,
    STAGES,
};

/// A message that carries its frame's stamp: what a stage of a row puts out, so that the next
/// one is handed it at the time it was finished.
pub trait Stamped: Message {
    fn stamp(&self) -> &FrameStamp;
}

macro_rules! stamped {
    ($($ty:ty),+) => {$(
        impl Stamped for $ty {
            fn stamp(&self) -> &FrameStamp {
                &self.stamp
            }
        }
    )+};
}

stamped!(MarkerMessage, AttitudeMessage, LandingDecision);

/// Stages in a row, in pipeline order (a tuple of them): the first takes the frames in, each
/// later one the output of the one before.
pub trait StageRow: Sized {
    /// Their entries in the process table, in order.
    const PROCESSES: &'static [ProcessInfo];
    /// Their places in the pipeline, in order.
    const PLACES: &'static [PipelineStage];
    /// What each of them made of one frame, in order.
    type Outputs;
    /// The last of them: the row's output is its.
    type Last: Stage;

    /// Each stage as the configuration says (see [`Stage::from_config`]).
    fn from_config(config: &PipelineConfig, joined_late: bool) -> Result<Self, ConfigError>;

    /// One frame through every stage in turn: the first receives it at `received_ns`; the one
    /// at index k of the row (from 1) receives the output of the one before at
    /// `received(k, finished_ns)`, `finished_ns` being when that one finished it. `lap` is
    /// called as each stage has finished.
    fn step(
        &mut self,
        frame: Frame<'_>,
        received_ns: u64,
        received: &mut dyn FnMut(usize, u64) -> u64,
        lap: &mut dyn FnMut(),
    ) -> Self::Outputs;

    /// Every stage's deferred work ([`Stage::after_outputs`]), in order.
    fn after_outputs(&mut self);

    /// A vehicle attitude sample, to every stage that follows the vehicle stream (the ones that
    /// list it in [`Stage::SIDE_INPUTS`]).
    fn vehicle_sample(&mut self, sample: &VehicleSample);

    /// The last stage.
    fn last(&self) -> &Self::Last;
    fn last_mut(&mut self) -> &mut Self::Last;
}

/// Whether a row's places are the stage table's, every stage once, in its order (a compile-time
/// check of [`crate::stages::FrameStages`]).
pub const fn places_follow_the_table<R: StageRow>() -> bool {
    if R::PLACES.len() != STAGES {
        return false;
    }
    let mut i = 0;
    while i < STAGES {
        if R::PLACES[i] as usize != PipelineStage::ALL[i] as usize {
            return false;
        }
        i += 1;
    }
    true
}

/// `StageRow` for the tuple `(A, B, ...)`: `stage_row!(A a, B b after A a, ...; last B 1)`, each
/// stage with the variable of its output and the stage it follows; the last with its index.
macro_rules! stage_row {
    ($A:ident $a:ident $(, $B:ident $b:ident after $P:ident $p:ident)*; last $L:ident $last:tt) => {
        impl<$A $(, $B)*> StageRow for ($A, $($B,)*)
        where
            $A: Stage<Input = Frames>,
            $A::Output: Stamped,
            $($B: Stage<Input = $P::Output>, $B::Output: Stamped,)*
        {
            const PROCESSES: &'static [ProcessInfo] = &[process::<$A>() $(, process::<$B>())*];
            const PLACES: &'static [PipelineStage] = &[$A::PLACE $(, $B::PLACE)*];
            type Outputs = ($A::Output, $($B::Output,)*);
            type Last = $L;

            fn from_config(config: &PipelineConfig, joined_late: bool) -> Result<Self, ConfigError> {
                Ok(($A::from_config(config, joined_late)?, $($B::from_config(config, joined_late)?,)*))
            }

            #[allow(unused_variables, unused_mut, unused_assignments)]
            fn step(
                &mut self,
                frame: Frame<'_>,
                received_ns: u64,
                received: &mut dyn FnMut(usize, u64) -> u64,
                lap: &mut dyn FnMut(),
            ) -> Self::Outputs {
                let ($a, $($b,)*) = self;
                let $a = $a.step(frame, received_ns);
                lap();
                let mut k = 0;
                $(
                    k += 1;
                    let finished_ns = $p.stamp().times[$P::PLACE].finished_ns;
                    let $b = $b.step(&$p, received(k, finished_ns));
                    lap();
                )*
                ($a, $($b,)*)
            }

            fn after_outputs(&mut self) {
                let ($a, $($b,)*) = self;
                $a.after_outputs();
                $($b.after_outputs();)*
            }

            fn vehicle_sample(&mut self, sample: &VehicleSample) {
                let ($a, $($b,)*) = self;
                if $A::SIDE_INPUTS.contains(&VehicleSample::SERVICE) {
                    $a.vehicle_sample(sample);
                }
                $(if $B::SIDE_INPUTS.contains(&VehicleSample::SERVICE) {
                    $b.vehicle_sample(sample);
                })*
            }

            fn last(&self) -> &$L {
                &self.$last
            }

            fn last_mut(&mut self) -> &mut $L {
                &mut self.$last
            }
        }
    };
}

stage_row!(A a; last A 0);
stage_row!(A a, B b after A a; last B 1);
stage_row!(A a, B b after A a, C c after B b; last C 2);
stage_row!(A a, B b after A a, C c after B b, D d after C c; last D 3);
stage_row!(A a, B b after A a, C c after B b, D d after C c, E e after D d; last E 4);

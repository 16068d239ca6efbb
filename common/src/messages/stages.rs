//! The pipeline's stages, in order: the one table of them.
//!
//! Every frame comes from the source (capture) and passes the stages in this order. The
//! messages' per-stage times and drop counts ([`super::StageTimes`], [`super::DropCounts`]) and
//! the latency intervals ([`super::LatencyInterval`]) are indexed by a stage's place here, and
//! the names a user or a tool reads (a recording's JSON, the decisions CSV, the launcher's
//! report, the viewer's series) are spelled from it. The runtime's process table
//! (`deckwatch_runtime::stages::PROCESSES`) takes the source's name and each stage's
//! (`Stage::PLACE`) from here, and its row of stages (`stages::FrameStages`, which the
//! in-process chain runs) is checked against this order when it compiles.

/// `source: "name"; Variant => "name", ...`: [`SOURCE`], [`PipelineStage`] (its variants in
/// pipeline order), [`STAGES`] and the names spelled from them.
macro_rules! pipeline_stages {
    (source: $source:literal; $first:ident => $first_name:literal $(, $stage:ident => $name:literal)* $(,)?) => {
        /// The process every frame comes from (`capture`). It is no stage (it has no input): its
        /// times and counts are fields of their own (`captured_ns`, `published_ns`; `capture`,
        /// `bad_frames`).
        pub const SOURCE: &str = $source;

        /// The number of stages after the source.
        pub const STAGES: usize = <[&str]>::len(&[$first_name $(, $name)*]);

        /// A stage a frame passes after the source: its place in the pipeline indexes the
        /// messages' per-stage times and drop counts.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum PipelineStage {
            $first,
            $($stage,)*
        }

        impl PipelineStage {
            /// Every stage, in pipeline order.
            pub const ALL: [Self; STAGES] = [Self::$first $(, Self::$stage)*];

            /// Its name: its process (node, binary `deckwatch-<name>`, log lines), its drop
            /// count's, its latency interval's.
            pub const fn name(self) -> &'static str {
                match self {
                    Self::$first => $first_name,
                    $(Self::$stage => $name,)*
                }
            }

            /// The name of the time it received a frame (`detect_received_ns`).
            pub const fn received_name(self) -> &'static str {
                match self {
                    Self::$first => concat!($first_name, "_received_ns"),
                    $(Self::$stage => concat!($name, "_received_ns"),)*
                }
            }

            /// The name of the time it finished a frame (`detect_finished_ns`).
            pub const fn finished_name(self) -> &'static str {
                match self {
                    Self::$first => concat!($first_name, "_finished_ns"),
                    $(Self::$stage => concat!($name, "_finished_ns"),)*
                }
            }
        }

        /// The frame's hop from the source to the first stage, as a latency interval's name
        /// (`capture->detect`).
        pub(super) const HOP_NAME: &str = concat!($source, "->", $first_name);
    };
}

pipeline_stages! {
    source: "capture";
    Detect => "detect",
    Estimate => "estimate",
    Decide => "decide",
}

impl PipelineStage {
    /// The first stage: it takes the source's frames in.
    pub const FIRST: Self = Self::ALL[0];
    /// The last stage: its output is the pipeline's.
    pub const LAST: Self = Self::ALL[STAGES - 1];

    /// Its place: 0 for the first stage.
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The stage before it (None: the first, whose input is the source's).
    pub const fn previous(self) -> Option<Self> {
        match self.index() {
            0 => None,
            i => Some(Self::ALL[i - 1]),
        }
    }

    /// The stage [`Self::name`] calls `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_spells_every_name() {
        assert_eq!(SOURCE, "capture");
        let names: Vec<&str> = PipelineStage::ALL.iter().map(|s| s.name()).collect();
        assert_eq!(names, ["detect", "estimate", "decide"]);
        assert_eq!(PipelineStage::Estimate.received_name(), "estimate_received_ns");
        assert_eq!(PipelineStage::Decide.finished_name(), "decide_finished_ns");
        assert_eq!(HOP_NAME, "capture->detect");
        for (i, s) in PipelineStage::ALL.into_iter().enumerate() {
            assert_eq!(s.index(), i);
            assert_eq!(PipelineStage::from_name(s.name()), Some(s));
            assert_eq!(s.previous(), i.checked_sub(1).map(|p| PipelineStage::ALL[p]));
        }
        assert_eq!(
            (PipelineStage::FIRST, PipelineStage::LAST),
            (PipelineStage::Detect, PipelineStage::Decide)
        );
    }
}

//! Fieldless enums' names, declared once beside the variants: the list, each variant's name
//! (command line, reports, recordings' text) and the way back from a name.

/// Implements `ALL` (every value, in the order listed), `name()` and `from_name()` for a
/// fieldless enum from one list of `Variant => "name"`. The list must name every variant:
/// `name()` is an exhaustive match, so a variant added to the enum and not here fails to
/// compile. Names must be distinct (`named_enum_tests` checks the ones declared here).
#[macro_export]
macro_rules! named_enum {
    ($ty:ident, [$($variant:ident => $name:literal),+ $(,)?]) => {
        impl $ty {
            /// Every value, in the order of its declaration's list.
            pub const ALL: [Self; <[&str]>::len(&[$($name),+])] = [$(Self::$variant),+];

            /// The value's name, as the command line, reports and recordings write it.
            pub fn name(&self) -> &'static str {
                match self {
                    $(Self::$variant => $name,)+
                }
            }

            /// The value [`Self::name`] calls `name`.
            pub fn from_name(name: &str) -> Option<Self> {
                Self::ALL.into_iter().find(|v| v.name() == name)
            }

            /// [`Self::from_name`] with an error that lists the names: a command-line value
            /// (clap's `value_parser = Type::parse`).
            pub fn parse(name: &str) -> Result<Self, $crate::names::UnknownName> {
                Self::from_name(name).ok_or_else(|| $crate::names::UnknownName {
                    name: name.to_string(),
                    known: Self::ALL.iter().map(|v| v.name()).collect::<Vec<_>>().join(", "),
                })
            }
        }
    };
}

/// A name that is none of an enum's ([`named_enum!`]'s `parse`).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown `{name}` ({known})")]
pub struct UnknownName {
    pub name: String,
    /// Every name, in the enum's order.
    pub known: String,
}

#[cfg(test)]
mod named_enum_tests {
    use crate::messages::{DecisionReason, DecisionState, FrameSource, LatencyInterval};
    use crate::vehicle::Compensation;

    fn distinct_and_round_trip<T: Copy + PartialEq + std::fmt::Debug>(
        all: &[T],
        name: fn(&T) -> &'static str,
        from_name: fn(&str) -> Option<T>,
    ) {
        let mut names: Vec<&str> = all.iter().map(name).collect();
        for v in all {
            assert_eq!(from_name(name(v)), Some(*v));
        }
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), all.len(), "a name used twice");
        assert_eq!(from_name("no-such-name"), None);
    }

    #[test]
    fn a_name_parses_and_an_unknown_one_lists_the_names() {
        use crate::messages::EstimatorKind;
        assert_eq!(EstimatorKind::parse("full-pose"), Ok(EstimatorKind::FullPose));
        assert_eq!(EstimatorKind::ALL[0], EstimatorKind::FullPose);
        assert_eq!(
            EstimatorKind::parse("pose").unwrap_err().to_string(),
            "unknown `pose` (full-pose, paper-atan2, paper-printed, paper-fitted-major-axis)"
        );
    }

    #[test]
    fn every_name_is_distinct_and_reads_back() {
        distinct_and_round_trip(
            &crate::messages::EstimatorKind::ALL,
            crate::messages::EstimatorKind::name,
            crate::messages::EstimatorKind::from_name,
        );
        distinct_and_round_trip(&DecisionState::ALL, DecisionState::name, DecisionState::from_name);
        distinct_and_round_trip(
            &DecisionReason::ALL,
            DecisionReason::name,
            DecisionReason::from_name,
        );
        distinct_and_round_trip(&Compensation::ALL, Compensation::name, Compensation::from_name);
        use crate::vehicle::VehicleAttitudeSource as Source;
        distinct_and_round_trip(&Source::ALL, Source::name, Source::from_name);
        distinct_and_round_trip(
            &LatencyInterval::ALL,
            LatencyInterval::name,
            LatencyInterval::from_name,
        );
        distinct_and_round_trip(&FrameSource::ALL, FrameSource::name, FrameSource::from_name);
    }
}

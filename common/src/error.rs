//! The errors of a value out of range: a field of one of common's models (camera, deck), or an
//! option of a command or a simulation, named as the user gave it.

/// A field whose value is not usable: which, and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("field `{field}`: {problem}")]
pub struct InvalidField {
    pub field: String,
    pub problem: String,
}

/// An option (a command-line flag or a setting) whose value is not usable: which, as the user
/// wrote it (`--rate`, `--drop-share`), and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{option}: {problem}")]
pub struct InvalidOption {
    pub option: String,
    pub problem: String,
}

impl InvalidOption {
    pub fn new(option: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            option: option.into(),
            problem: problem.into(),
        }
    }
}

impl InvalidField {
    pub fn new(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            problem: problem.into(),
        }
    }
}

/// The command line reports errors as text: `?` turns these into it there.
impl From<InvalidField> for String {
    fn from(e: InvalidField) -> Self {
        e.to_string()
    }
}

impl From<InvalidOption> for String {
    fn from(e: InvalidOption) -> Self {
        e.to_string()
    }
}

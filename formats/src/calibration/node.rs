//! The tree both readers produce (YAML subset and OpenCV XML), with the line of every value, and
//! typed look-ups whose errors name the file, the key and the line.

use super::{CalibrationError, CalibrationProblem};
use std::path::Path;

/// A value read from a calibration file.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Node {
    /// 1-based line the value starts on.
    pub line: usize,
    /// The YAML tag without its `!`s (`opencv-matrix`) or the XML `type_id` attribute.
    pub tag: Option<String>,
    pub value: Value,
}

#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Value {
    /// No value (`key:` with nothing after it, an empty XML element).
    Empty,
    /// Text as written, quotes removed.
    Scalar(String),
    Seq(Vec<Node>),
    /// Entries in file order; keys are unique (the readers refuse duplicates).
    Map(Vec<(String, Node)>),
}

impl Node {
    pub fn new(line: usize, value: Value) -> Self {
        Self {
            line,
            tag: None,
            value,
        }
    }

    /// The entry `key` of a mapping.
    pub fn get(&self, key: &str) -> Option<&Node> {
        match &self.value {
            Value::Map(entries) => entries.iter().find(|(k, _)| k == key).map(|(_, n)| n),
            _ => None,
        }
    }

    /// What the value is, for an error message.
    pub fn describe(&self) -> String {
        match &self.value {
            Value::Empty => "nothing".into(),
            Value::Scalar(s) if s.chars().count() > 40 => {
                format!("text `{}...`", s.chars().take(40).collect::<String>())
            }
            Value::Scalar(s) => format!("text `{s}`"),
            Value::Seq(items) => format!("a list of {}", items.len()),
            Value::Map(_) => "a mapping".into(),
        }
    }
}

/// Parses a number as the tools write it: Rust's float syntax plus YAML's `.nan`, `.inf`,
/// `-.inf` (OpenCV writes `.Nan`, `.Inf`). Non-finite values parse; callers refuse them with
/// the key.
pub(crate) fn parse_number(text: &str) -> Option<f64> {
    match text.to_ascii_lowercase().as_str() {
        ".nan" => Some(f64::NAN),
        ".inf" | "+.inf" => Some(f64::INFINITY),
        "-.inf" => Some(f64::NEG_INFINITY),
        // Rust also accepts "inf", "infinity" and "nan" in any case; those stay non-finite.
        other => other.parse().ok(),
    }
}

/// The file being read: builds located errors and does typed look-ups.
pub(crate) struct FileContext<'a> {
    pub path: &'a Path,
}

impl FileContext<'_> {
    pub fn error(&self, line: Option<usize>, key: &str, problem: CalibrationProblem) -> CalibrationError {
        CalibrationError {
            path: self.path.to_path_buf(),
            line,
            key: (!key.is_empty()).then(|| key.to_string()),
            problem,
        }
    }

    fn wrong_type(&self, node: &Node, key: &str, expected: &'static str) -> CalibrationError {
        self.error(
            Some(node.line),
            key,
            CalibrationProblem::WrongType {
                expected,
                found: node.describe(),
            },
        )
    }

    /// The entry `key` of the mapping `map` (whose own key is `map_key`, "" at the top).
    pub fn required<'n>(
        &self,
        map: &'n Node,
        map_key: &str,
        key: &str,
    ) -> Result<&'n Node, CalibrationError> {
        let full = join_key(map_key, key);
        if !matches!(map.value, Value::Map(_)) {
            return Err(self.wrong_type(map, map_key, "a mapping"));
        }
        // The line of the mapping's own key; the top level has none worth naming.
        let line = (!map_key.is_empty()).then_some(map.line);
        map.get(key)
            .ok_or_else(|| self.error(line, &full, CalibrationProblem::MissingKey))
    }

    /// A finite number.
    pub fn number(&self, node: &Node, key: &str) -> Result<f64, CalibrationError> {
        let Value::Scalar(text) = &node.value else {
            return Err(self.wrong_type(node, key, "a number"));
        };
        let v = parse_number(text.trim()).ok_or_else(|| self.wrong_type(node, key, "a number"))?;
        if !v.is_finite() {
            return Err(self.error(
                Some(node.line),
                key,
                CalibrationProblem::NotFinite { text: text.clone() },
            ));
        }
        Ok(v)
    }

    /// A whole number within `0..=u32::MAX` (image sizes, matrix shapes).
    pub fn whole_number(&self, node: &Node, key: &str) -> Result<u32, CalibrationError> {
        let Value::Scalar(text) = &node.value else {
            return Err(self.wrong_type(node, key, "a whole number"));
        };
        text.trim()
            .parse()
            .map_err(|_| self.wrong_type(node, key, "a whole number"))
    }

    /// Text (a model name, a camera name).
    pub fn text<'n>(&self, node: &'n Node, key: &str) -> Result<&'n str, CalibrationError> {
        match &node.value {
            Value::Scalar(text) => Ok(text.trim()),
            _ => Err(self.wrong_type(node, key, "text")),
        }
    }

    /// A list of finite numbers; an error names the element (`key[i]`) and its line.
    pub fn numbers(&self, node: &Node, key: &str) -> Result<Vec<f64>, CalibrationError> {
        match &node.value {
            Value::Seq(items) => items
                .iter()
                .enumerate()
                .map(|(i, item)| self.number(item, &format!("{key}[{i}]")))
                .collect(),
            // `[]` in YAML, an empty element in XML.
            Value::Empty => Ok(Vec::new()),
            _ => Err(self.wrong_type(node, key, "a list of numbers")),
        }
    }

    /// A matrix written as `{rows, cols, data}` (ROS) or `!!opencv-matrix {rows, cols, dt,
    /// data}` (OpenCV): its shape and its row-major values, the count checked against the shape.
    pub fn matrix(&self, node: &Node, key: &str) -> Result<Matrix, CalibrationError> {
        let rows = self.whole_number(self.required(node, key, "rows")?, &join_key(key, "rows"))?;
        let cols = self.whole_number(self.required(node, key, "cols")?, &join_key(key, "cols"))?;
        let data_key = join_key(key, "data");
        let data_node = self.required(node, key, "data")?;
        let values = self.numbers(data_node, &data_key)?;
        // The shape is only compared, never allocated from.
        let expected = u64::from(rows) * u64::from(cols);
        if values.len() as u64 != expected {
            return Err(self.error(
                Some(data_node.line),
                &data_key,
                CalibrationProblem::WrongShape {
                    expected: format!("{rows}x{cols} = {expected} values (rows x cols)"),
                    found: format!("{} values", values.len()),
                },
            ));
        }
        Ok(Matrix {
            rows,
            cols,
            values,
            line: node.line,
        })
    }
}

/// A matrix read from a file, row-major.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Matrix {
    pub rows: u32,
    pub cols: u32,
    pub values: Vec<f64>,
    /// Line of the matrix's key.
    pub line: usize,
}

impl Matrix {
    /// `3x3`.
    pub fn shape(&self) -> String {
        format!("{}x{}", self.rows, self.cols)
    }

    /// Whether it is one row or one column (a coefficient vector).
    pub fn is_vector(&self) -> bool {
        self.rows == 1 || self.cols == 1
    }
}

/// `parent.key`, or `key` at the top.
pub(crate) fn join_key(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_string()
    } else {
        format!("{parent}.{key}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar(line: usize, s: &str) -> Node {
        Node::new(line, Value::Scalar(s.into()))
    }

    #[test]
    fn numbers_parse_as_the_tools_write_them() {
        for (text, v) in [("1.", 1.0), ("-2.5e-3", -2.5e-3), ("0", 0.0), (".5", 0.5)] {
            assert_eq!(parse_number(text), Some(v), "{text}");
        }
        assert!(parse_number(".Nan").unwrap().is_nan());
        assert_eq!(parse_number("-.Inf"), Some(f64::NEG_INFINITY));
        assert_eq!(parse_number("abc"), None);
        assert_eq!(parse_number(""), None);
    }

    #[test]
    fn look_ups_name_the_key_and_line() {
        let ctx = FileContext {
            path: Path::new("cal.yaml"),
        };
        let map = Node::new(
            3,
            Value::Map(vec![
                ("rows".into(), scalar(4, "3")),
                ("cols".into(), scalar(5, "3")),
                (
                    "data".into(),
                    Node::new(6, Value::Seq(vec![scalar(6, "1"), scalar(7, ".nan")])),
                ),
            ]),
        );
        let e = ctx.matrix(&map, "camera_matrix").unwrap_err().to_string();
        assert_eq!(
            e,
            "cal.yaml:7: key `camera_matrix.data[1]`: `.nan` is not a finite number"
        );
        let e = ctx.required(&map, "camera_matrix", "dt").unwrap_err().to_string();
        assert_eq!(e, "cal.yaml:3: key `camera_matrix.dt`: missing");
        let e = ctx.number(&map, "camera_matrix").unwrap_err().to_string();
        assert!(e.contains("expected a number, found a mapping"), "{e}");
        let e = ctx
            .whole_number(&scalar(9, "-1"), "image_width")
            .unwrap_err()
            .to_string();
        assert!(e.contains("expected a whole number, found text `-1`"), "{e}");
    }
}

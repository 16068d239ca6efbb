//! A strict reader for the YAML that calibration tools write: block mappings and lists, flow
//! lists (`[1., 0., 320.]`, continued over lines), plain and quoted text, tags (`!!opencv-matrix`),
//! comments, one document with optional `%YAML` directives and `---`.
//!
//! Why not a YAML crate: none is in the lock file; OpenCV's `%YAML:1.0` header is not valid YAML,
//! so a spec-following parser needs the file rewritten first; and ROS, OpenCV and Kalibr write
//! only the subset above. Reading exactly that keeps every value's line for the error messages,
//! adds no dependency, and refuses what the tools never write (anchors, aliases, block text,
//! flow mappings, multi-line text) by name and line instead of guessing.

use super::node::{Node, Value};

/// The deepest nesting accepted: a calibration nests three levels; this bounds the recursion.
const MAX_DEPTH: usize = 32;

/// A syntax error at a 1-based line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub(crate) struct YamlError {
    pub line: usize,
    pub message: String,
}

fn err(line: usize, message: impl Into<String>) -> YamlError {
    YamlError {
        line,
        message: message.into(),
    }
}

/// Reads a document into a tree.
pub(crate) fn parse(text: &str) -> Result<Node, YamlError> {
    let lines = content_lines(text)?;
    let Some(first) = lines.first() else {
        return Err(err(1, "the file has no content"));
    };
    let indent = first.indent;
    let mut parser = Parser { lines, pos: 0 };
    let node = parser.block(indent, 0)?;
    if let Some(line) = parser.peek() {
        return Err(err(
            line.number,
            format!(
                "unexpected `{}` (indentation {})",
                shorten(line.text),
                line.indent
            ),
        ));
    }
    Ok(node)
}

/// A line with content: its number, indentation and text (comment and trailing space removed).
#[derive(Debug, Clone, Copy)]
struct Line<'a> {
    number: usize,
    indent: usize,
    text: &'a str,
}

fn content_lines(text: &str) -> Result<Vec<Line<'_>>, YamlError> {
    let mut lines = Vec::new();
    let mut in_document = false;
    let mut ended = false;
    for (i, raw) in text.lines().enumerate() {
        let number = i + 1;
        let raw = if i == 0 {
            raw.strip_prefix('\u{feff}').unwrap_or(raw)
        } else {
            raw
        };
        let content = strip_comment(raw).trim_end();
        let text = content.trim_start();
        if text.is_empty() {
            continue;
        }
        let indent = content.len() - text.len();
        if content[..indent].contains('\t') {
            return Err(err(number, "a tab in the indentation (YAML indents with spaces)"));
        }
        if indent == 0 && text.starts_with('%') {
            // `%YAML:1.0` (OpenCV's own spelling) or `%YAML 1.2`: nothing to keep.
            if in_document {
                return Err(err(number, "a `%` directive inside the document"));
            }
            continue;
        }
        if indent == 0 && (text == "---" || text.starts_with("--- ")) {
            if in_document {
                return Err(err(number, "a second document (`---`): one calibration per file"));
            }
            if text.len() > 3 {
                return Err(err(
                    number,
                    "text after `---`: put the document on the next lines",
                ));
            }
            in_document = true;
            continue;
        }
        if indent == 0 && text == "..." {
            ended = true;
            continue;
        }
        if ended {
            return Err(err(number, "text after the end of the document (`...`)"));
        }
        in_document = true;
        lines.push(Line { number, indent, text });
    }
    Ok(lines)
}

/// The line without its comment: `#` at the start or after a space, outside quotes.
fn strip_comment(line: &str) -> &str {
    let mut quote: Option<char> = None;
    let mut prev: Option<char> = None;
    let mut chars = line.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        match quote {
            Some('"') if c == '\\' => {
                chars.next();
            }
            Some(q) if c == q => {
                // '' inside single quotes is an escaped quote.
                if q == '\'' && chars.peek().is_some_and(|&(_, n)| n == '\'') {
                    chars.next();
                } else {
                    quote = None;
                }
            }
            Some(_) => {}
            // A quote opens quoted text only where a value starts, not inside a word (it's).
            None if (c == '"' || c == '\'')
                && prev.is_none_or(|p| p.is_whitespace() || p == '[' || p == ',') =>
            {
                quote = Some(c)
            }
            None if c == '#' && prev.is_none_or(char::is_whitespace) => return &line[..i],
            None => {}
        }
        prev = Some(c);
    }
    line
}

/// Quoted text at the start of `text`: the text without quotes, and what follows it.
fn read_quoted(text: &str, line: usize) -> Result<(String, &str), YamlError> {
    let mut chars = text.char_indices();
    let Some((_, quote)) = chars.next() else {
        return Err(err(line, "expected quoted text"));
    };
    let mut out = String::new();
    while let Some((i, c)) = chars.next() {
        if c == quote {
            if quote == '\'' && text[i + 1..].starts_with('\'') {
                chars.next();
                out.push('\'');
                continue;
            }
            return Ok((out, &text[i + 1..]));
        }
        if quote == '"' && c == '\\' {
            let escaped = match chars.next().map(|(_, e)| e) {
                Some('"') => '"',
                Some('\\') => '\\',
                Some('/') => '/',
                Some('n') => '\n',
                Some('t') => '\t',
                Some('r') => '\r',
                Some('0') => '\0',
                other => {
                    return Err(err(
                        line,
                        format!("unsupported escape `\\{}` in quoted text", other.unwrap_or(' ')),
                    ))
                }
            };
            out.push(escaped);
        } else {
            out.push(c);
        }
    }
    Err(err(
        line,
        "quoted text without its closing quote (quoted text over several lines is not supported)",
    ))
}

fn is_item(text: &str) -> bool {
    text == "-" || text.starts_with("- ")
}

/// `key: rest` split at the key's colon; None when the line is not a mapping entry.
fn split_key(text: &str, line: usize) -> Result<Option<(String, &str)>, YamlError> {
    fn after_colon(after: &str) -> Option<&str> {
        let rest = after.strip_prefix(':')?;
        (rest.is_empty() || rest.starts_with(' ')).then(|| rest.trim())
    }
    if text.starts_with('"') || text.starts_with('\'') {
        let (key, after) = read_quoted(text, line)?;
        return Ok(after_colon(after.trim_start()).map(|rest| (key, rest)));
    }
    if text.starts_with(['[', '{', '!', '&', '*', '|', '>', '#']) {
        return Ok(None);
    }
    for (i, c) in text.char_indices() {
        if c == ':' {
            if let Some(rest) = after_colon(&text[i..]) {
                return Ok(Some((text[..i].trim_end().to_string(), rest)));
            }
        }
    }
    Ok(None)
}

/// `!!tag rest` or `!tag rest`: the tag's name and the rest.
fn split_tag(text: &str, line: usize) -> Result<(Option<String>, &str), YamlError> {
    let Some(tagged) = text.strip_prefix('!') else {
        return Ok((None, text));
    };
    let tagged = tagged.strip_prefix('!').unwrap_or(tagged);
    let end = tagged.find(' ').unwrap_or(tagged.len());
    if end == 0 {
        return Err(err(line, "an empty tag `!`"));
    }
    Ok((Some(tagged[..end].to_string()), tagged[end..].trim_start()))
}

fn shorten(text: &str) -> String {
    if text.chars().count() > 40 {
        format!("{}...", text.chars().take(40).collect::<String>())
    } else {
        text.to_string()
    }
}

/// Where a flow list is being read: its current line and the rest of that line.
struct FlowCursor<'a> {
    line: usize,
    rest: &'a str,
}

struct Parser<'a> {
    lines: Vec<Line<'a>>,
    pos: usize,
}

impl<'a> Parser<'a> {
    fn peek(&self) -> Option<&Line<'a>> {
        self.lines.get(self.pos)
    }

    /// The block (mapping, list or a lone value) starting at the current line, at `indent`.
    fn block(&mut self, indent: usize, depth: usize) -> Result<Node, YamlError> {
        let line = self.lines[self.pos];
        if depth > MAX_DEPTH {
            return Err(err(line.number, format!("nested deeper than {MAX_DEPTH} levels")));
        }
        if is_item(line.text) {
            self.list(indent, depth)
        } else if split_key(line.text, line.number)?.is_some() {
            self.mapping(indent, depth)
        } else {
            self.pos += 1;
            self.value(line.text, line.number, indent, depth, false)
        }
    }

    fn mapping(&mut self, indent: usize, depth: usize) -> Result<Node, YamlError> {
        let first_line = self.lines[self.pos].number;
        let mut entries: Vec<(String, Node)> = Vec::new();
        let mut key_lines = Vec::new();
        while let Some(&line) = self.peek() {
            if line.indent < indent {
                break;
            }
            if line.indent > indent {
                return Err(err(line.number, "unexpected indentation"));
            }
            if is_item(line.text) {
                return Err(err(line.number, "a list item (`- `) where a `key:` was expected"));
            }
            let Some((key, rest)) = split_key(line.text, line.number)? else {
                return Err(err(
                    line.number,
                    format!("expected `key: value`, found `{}`", shorten(line.text)),
                ));
            };
            if let Some(i) = entries.iter().position(|(k, _)| *k == key) {
                return Err(err(
                    line.number,
                    format!("key `{key}` appears twice (first on line {})", key_lines[i]),
                ));
            }
            self.pos += 1;
            let node = self.value(rest, line.number, indent, depth + 1, true)?;
            entries.push((key, node));
            key_lines.push(line.number);
        }
        Ok(Node::new(first_line, Value::Map(entries)))
    }

    fn list(&mut self, indent: usize, depth: usize) -> Result<Node, YamlError> {
        let first_line = self.lines[self.pos].number;
        let mut items = Vec::new();
        while let Some(&line) = self.peek() {
            if line.indent > indent {
                return Err(err(line.number, "unexpected indentation"));
            }
            if line.indent < indent || !is_item(line.text) {
                break;
            }
            let rest = line.text[1..].trim_start();
            let item_indent = indent + (line.text.len() - rest.len());
            let item = if !rest.is_empty() && (is_item(rest) || split_key(rest, line.number)?.is_some()) {
                // `- key: value` or `- - x`: the item is a block starting at the text's column.
                self.lines[self.pos] = Line {
                    number: line.number,
                    indent: item_indent,
                    text: rest,
                };
                self.block(item_indent, depth + 1)?
            } else {
                self.pos += 1;
                self.value(rest, line.number, indent, depth + 1, false)?
            };
            items.push(item);
        }
        Ok(Node::new(first_line, Value::Seq(items)))
    }

    /// The value after `key:` or `- ` on line `number`: `text`, or when that is empty the
    /// block on the following lines. In a mapping, a list may sit at the key's own indentation.
    fn value(
        &mut self,
        text: &'a str,
        number: usize,
        parent_indent: usize,
        depth: usize,
        in_mapping: bool,
    ) -> Result<Node, YamlError> {
        if depth > MAX_DEPTH {
            return Err(err(number, format!("nested deeper than {MAX_DEPTH} levels")));
        }
        let (tag, text) = split_tag(text, number)?;
        let mut node = if text.is_empty() {
            match self.peek() {
                Some(&next)
                    if next.indent > parent_indent
                        || (in_mapping && next.indent == parent_indent && is_item(next.text)) =>
                {
                    let mut node = self.block(next.indent, depth)?;
                    // A missing key inside is reported at the key that holds the block.
                    node.line = number;
                    node
                }
                _ => Node::new(number, Value::Empty),
            }
        } else {
            let node = match text.as_bytes()[0] {
                b'[' => {
                    let mut cursor = FlowCursor {
                        line: number,
                        rest: text,
                    };
                    let node = self.flow_list(&mut cursor, depth)?;
                    if !cursor.rest.trim().is_empty() {
                        return Err(err(
                            cursor.line,
                            format!(
                                "unexpected `{}` after the list's `]`",
                                shorten(cursor.rest.trim())
                            ),
                        ));
                    }
                    node
                }
                b'{' => {
                    return Err(err(
                        number,
                        "a flow mapping `{...}` is not supported: write it as indented `key: value` lines",
                    ))
                }
                b'&' | b'*' => return Err(err(number, "anchors and aliases (`&`, `*`) are not supported")),
                b'|' | b'>' => return Err(err(number, "block text (`|`, `>`) is not supported")),
                b'"' | b'\'' => {
                    let (s, after) = read_quoted(text, number)?;
                    if !after.trim().is_empty() {
                        return Err(err(number, "unexpected text after the closing quote"));
                    }
                    Node::new(number, Value::Scalar(s))
                }
                _ => Node::new(number, Value::Scalar(text.to_string())),
            };
            // A value continued on more-indented lines is something these tools never write.
            if let Some(next) = self.peek() {
                if next.indent > parent_indent {
                    return Err(err(
                        next.number,
                        "unexpected indentation (a value continued on the next line is not supported)",
                    ));
                }
            }
            node
        };
        node.tag = tag;
        Ok(node)
    }

    /// Skips spaces; at the end of a line, continues on the next (a list may span lines).
    fn flow_skip(&mut self, cursor: &mut FlowCursor<'a>) -> Result<(), YamlError> {
        loop {
            cursor.rest = cursor.rest.trim_start();
            if !cursor.rest.is_empty() {
                return Ok(());
            }
            let Some(&next) = self.peek() else {
                return Err(err(
                    cursor.line,
                    "the list's `[` is not closed before the end of the file (truncated?)",
                ));
            };
            self.pos += 1;
            *cursor = FlowCursor {
                line: next.number,
                rest: next.text,
            };
        }
    }

    /// `[item, item, ...]` starting at the cursor.
    fn flow_list(&mut self, cursor: &mut FlowCursor<'a>, depth: usize) -> Result<Node, YamlError> {
        if depth > MAX_DEPTH {
            return Err(err(cursor.line, format!("nested deeper than {MAX_DEPTH} levels")));
        }
        let line = cursor.line;
        cursor.rest = &cursor.rest[1..];
        let mut items = Vec::new();
        loop {
            self.flow_skip(cursor)?;
            if let Some(rest) = cursor.rest.strip_prefix(']') {
                cursor.rest = rest;
                return Ok(Node::new(line, Value::Seq(items)));
            }
            if !items.is_empty() {
                let Some(rest) = cursor.rest.strip_prefix(',') else {
                    return Err(err(
                        cursor.line,
                        format!("expected `,` or `]` in a list, found `{}`", shorten(cursor.rest)),
                    ));
                };
                cursor.rest = rest;
                self.flow_skip(cursor)?;
                if let Some(rest) = cursor.rest.strip_prefix(']') {
                    cursor.rest = rest; // a trailing comma
                    return Ok(Node::new(line, Value::Seq(items)));
                }
            }
            let item = match cursor.rest.as_bytes()[0] {
                b'[' => self.flow_list(cursor, depth + 1)?,
                b'{' => {
                    return Err(err(
                        cursor.line,
                        "a flow mapping `{...}` in a list is not supported",
                    ))
                }
                b',' => return Err(err(cursor.line, "an empty item in a list")),
                b'"' | b'\'' => {
                    let (s, after) = read_quoted(cursor.rest, cursor.line)?;
                    cursor.rest = after;
                    Node::new(cursor.line, Value::Scalar(s))
                }
                _ => {
                    let end = cursor
                        .rest
                        .find([',', ']', '[', '{', '}'])
                        .unwrap_or(cursor.rest.len());
                    let text = cursor.rest[..end].trim_end();
                    if text.contains(": ") || text.ends_with(':') {
                        return Err(err(cursor.line, "a `key: value` pair in a list is not supported"));
                    }
                    cursor.rest = &cursor.rest[end..];
                    Node::new(cursor.line, Value::Scalar(text.to_string()))
                }
            };
            items.push(item);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar(node: &Node) -> &str {
        match &node.value {
            Value::Scalar(s) => s,
            other => panic!("not a scalar: {other:?}"),
        }
    }

    fn list(node: &Node) -> Vec<&str> {
        match &node.value {
            Value::Seq(items) => items.iter().map(scalar).collect(),
            other => panic!("not a list: {other:?}"),
        }
    }

    #[test]
    fn reads_opencv_yaml_with_its_header_tags_and_wrapped_lists() {
        let text = "%YAML:1.0\n---\ncalibration_time: \"Tue 03 Jun 2025 10:12:00 # not a comment\"\n\
                    image_width: 640 # a comment\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n\
                    \x20  data: [ 5.0e+02, 0., 3.2e+02, 0.,\n       5.0e+02, 2.4e+02,\n       0., 0., 1. ]\n";
        let doc = parse(text).unwrap();
        assert_eq!(
            scalar(doc.get("calibration_time").unwrap()),
            "Tue 03 Jun 2025 10:12:00 # not a comment"
        );
        assert_eq!(scalar(doc.get("image_width").unwrap()), "640");
        let k = doc.get("camera_matrix").unwrap();
        assert_eq!(k.tag.as_deref(), Some("opencv-matrix"));
        assert_eq!(k.line, 5);
        assert_eq!(scalar(k.get("dt").unwrap()), "d");
        let data = k.get("data").unwrap();
        assert_eq!(list(data).len(), 9);
        let Value::Seq(items) = &data.value else {
            unreachable!()
        };
        assert_eq!((items[0].line, items[4].line, items[8].line), (9, 10, 11));
    }

    #[test]
    fn reads_kalibr_lists_of_lists_at_the_keys_indentation() {
        let text = "cam0:\n  camera_model: pinhole\n  T_cam_imu:\n  - [1, 0, 0, 0.1]\n  - [0, 1, 0, 0]\n  \
                    intrinsics: [461.6, 460.2, 362.7, 246.0]\n  cam_overlaps: []\n  rostopic: /cam0/image_raw\n\
                    cam1:\n  items:\n    - name: a\n      value: 1\n    - 'it''s'\n    -\n";
        let doc = parse(text).unwrap();
        let cam0 = doc.get("cam0").unwrap();
        let t = cam0.get("T_cam_imu").unwrap();
        let Value::Seq(rows) = &t.value else {
            panic!("{t:?}")
        };
        assert_eq!(list(&rows[0]), ["1", "0", "0", "0.1"]);
        assert_eq!(list(cam0.get("intrinsics").unwrap()).len(), 4);
        assert_eq!(cam0.get("cam_overlaps").unwrap().value, Value::Seq(vec![]));
        assert_eq!(scalar(cam0.get("rostopic").unwrap()), "/cam0/image_raw");
        let Value::Seq(items) = &doc.get("cam1").unwrap().get("items").unwrap().value else {
            panic!()
        };
        assert_eq!(scalar(items[0].get("value").unwrap()), "1");
        assert_eq!(scalar(&items[1]), "it's");
        assert_eq!(items[2].value, Value::Empty);
    }

    #[test]
    fn refuses_what_the_tools_never_write_with_the_line() {
        let cases = [
            ("a: 1\na: 2\n", 2, "appears twice (first on line 1)"),
            ("a: [1, 2,\n  3\n", 2, "not closed before the end of the file"),
            ("a: [1, 2\nb: 3\n", 2, "expected `,` or `]`"),
            ("a: &x 1\n", 1, "anchors"),
            ("a: |\n  text\n", 1, "block text"),
            ("a: {b: 1}\n", 1, "flow mapping"),
            ("a: 1\n  b: 2\n", 2, "unexpected indentation"),
            ("a:\n\t b: 1\n", 2, "tab"),
            ("a: \"open\n", 1, "closing quote"),
            ("---\na: 1\n---\nb: 2\n", 3, "second document"),
            ("a: 1\ncamera_ma", 2, "expected `key: value`"),
            ("a: [1, 2] 3\n", 1, "after the list's `]`"),
            ("", 1, "no content"),
        ];
        for (text, line, message) in cases {
            let e = parse(text).unwrap_err();
            assert!(e.message.contains(message), "{text:?}: {e:?}");
            assert_eq!(e.line, line, "{text:?}: {e:?}");
        }
    }

    #[test]
    fn nesting_is_bounded() {
        let deep = "[".repeat(100) + &"]".repeat(100);
        assert!(parse(&format!("a: {deep}\n"))
            .unwrap_err()
            .message
            .contains("nested deeper"));
        let mut text = String::new();
        for i in 0..100 {
            text += &format!("{}k{i}:\n", " ".repeat(i));
        }
        assert!(parse(&text).unwrap_err().message.contains("nested deeper"));
    }
}

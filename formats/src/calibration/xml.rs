//! OpenCV FileStorage XML (`<opencv_storage>`) read into the same tree as the YAML: an element
//! with child elements is a mapping (a list when every child is `_`, OpenCV's list item), an
//! element with text is text, or a list when it holds several space-separated values (OpenCV
//! writes a matrix's `data` so); `type_id="opencv-matrix"` becomes the node's tag. quick-xml
//! does the XML (the lock file has it through MAVLink).

use super::node::{Node, Value};
use quick_xml::events::Event;
use quick_xml::Reader;

/// The deepest element nesting accepted (a calibration nests three levels).
const MAX_DEPTH: usize = 32;

/// A syntax error at a 1-based line.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub(crate) struct XmlError {
    pub line: usize,
    pub message: String,
}

/// An element being read.
struct Open {
    name: String,
    line: usize,
    type_id: Option<String>,
    /// Text pieces with the byte offset each starts at (for the lines of list values).
    text: Vec<(usize, String)>,
    children: Vec<(String, Node)>,
}

/// 1-based line of a byte offset.
struct LineIndex {
    starts: Vec<usize>,
}

impl LineIndex {
    fn new(text: &str) -> Self {
        let starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Self { starts }
    }
    fn line(&self, offset: usize) -> usize {
        self.starts.partition_point(|&s| s <= offset)
    }
}

/// Reads an OpenCV FileStorage XML document: the children of `<opencv_storage>` as a mapping.
pub(crate) fn parse(text: &str) -> Result<Node, XmlError> {
    let lines = LineIndex::new(text);
    let mut reader = Reader::from_str(text);
    let mut stack: Vec<Open> = Vec::new();
    let mut root: Option<Node> = None;
    loop {
        let before = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
        let event = reader.read_event().map_err(|e| XmlError {
            line: lines.line(usize::try_from(reader.error_position()).unwrap_or(usize::MAX)),
            message: format!("not well-formed XML: {e}"),
        })?;
        let after = usize::try_from(reader.buffer_position()).unwrap_or(usize::MAX);
        let line = lines.line(before + leading_space(&text[before.min(after)..after]));
        let is_empty = matches!(event, Event::Empty(_));
        match event {
            Event::Start(start) | Event::Empty(start) => {
                if root.is_some() {
                    return Err(XmlError {
                        line,
                        message: "an element after `</opencv_storage>`".into(),
                    });
                }
                if stack.len() >= MAX_DEPTH {
                    return Err(XmlError {
                        line,
                        message: format!("elements nested deeper than {MAX_DEPTH} levels"),
                    });
                }
                let name = String::from_utf8_lossy(start.name().as_ref()).into_owned();
                if stack.is_empty() && name != "opencv_storage" {
                    return Err(XmlError {
                        line,
                        message: format!("the root element is `<{name}>`, not OpenCV's `<opencv_storage>`"),
                    });
                }
                let type_id = start
                    .try_get_attribute("type_id")
                    .map_err(|e| XmlError {
                        line,
                        message: format!("a bad attribute in `<{name}>`: {e}"),
                    })?
                    .map(|a| String::from_utf8_lossy(&a.value).into_owned());
                stack.push(Open {
                    name,
                    line,
                    type_id,
                    text: Vec::new(),
                    children: Vec::new(),
                });
                if is_empty {
                    close(&mut stack, &mut root, &lines)?;
                }
            }
            Event::End(_) => close(&mut stack, &mut root, &lines)?,
            Event::Text(t) => {
                let piece = t.decode().map_err(|e| XmlError {
                    line,
                    message: format!("bad text: {e}"),
                })?;
                push_text(&mut stack, before, &piece, line)?;
            }
            Event::CData(t) => {
                let piece = t.decode().map_err(|e| XmlError {
                    line,
                    message: format!("bad text: {e}"),
                })?;
                push_text(&mut stack, before, &piece, line)?;
            }
            Event::GeneralRef(r) => {
                let resolved = match r.resolve_char_ref() {
                    Ok(Some(c)) => c,
                    _ => match &*r {
                        b"lt" => '<',
                        b"gt" => '>',
                        b"amp" => '&',
                        b"apos" => '\'',
                        b"quot" => '"',
                        other => {
                            return Err(XmlError {
                                line,
                                message: format!("unknown entity `&{};`", String::from_utf8_lossy(other)),
                            })
                        }
                    },
                };
                push_text(&mut stack, before, &resolved.to_string(), line)?;
            }
            Event::DocType(_) => {
                return Err(XmlError {
                    line,
                    message: "a DOCTYPE is not allowed in an OpenCV file".into(),
                })
            }
            Event::Eof => break,
            Event::Comment(_) | Event::Decl(_) | Event::PI(_) => {}
        }
    }
    if let Some(open) = stack.last() {
        return Err(XmlError {
            line: lines.line(text.len()),
            message: format!(
                "the file ends inside `<{}>` (opened on line {}): truncated?",
                open.name, open.line
            ),
        });
    }
    root.ok_or_else(|| XmlError {
        line: 1,
        message: "no `<opencv_storage>` element".into(),
    })
}

fn leading_space(s: &str) -> usize {
    s.len() - s.trim_start().len()
}

fn push_text(stack: &mut [Open], offset: usize, piece: &str, line: usize) -> Result<(), XmlError> {
    match stack.last_mut() {
        Some(open) => open.text.push((offset, piece.to_string())),
        None if piece.trim().is_empty() => {}
        None => {
            return Err(XmlError {
                line,
                message: "text outside `<opencv_storage>`".into(),
            })
        }
    }
    Ok(())
}

/// Closes the innermost element: builds its node and hands it to its parent (or makes it the
/// root).
fn close(stack: &mut Vec<Open>, root: &mut Option<Node>, lines: &LineIndex) -> Result<(), XmlError> {
    let Some(open) = stack.pop() else {
        return Err(XmlError {
            line: 1,
            message: "a closing tag without its opening tag".into(),
        });
    };
    let has_text = open.text.iter().any(|(_, t)| !t.trim().is_empty());
    let value = if !open.children.is_empty() {
        if has_text {
            return Err(XmlError {
                line: open.line,
                message: format!("`<{}>` mixes text and elements", open.name),
            });
        }
        if open.children.iter().all(|(name, _)| name == "_") {
            Value::Seq(open.children.into_iter().map(|(_, n)| n).collect())
        } else {
            let mut entries: Vec<(String, Node)> = Vec::new();
            for (name, node) in open.children {
                if let Some((_, first)) = entries.iter().find(|(k, _)| *k == name) {
                    return Err(XmlError {
                        line: node.line,
                        message: format!("`<{name}>` appears twice (first on line {})", first.line),
                    });
                }
                entries.push((name, node));
            }
            Value::Map(entries)
        }
    } else if !has_text {
        Value::Empty
    } else {
        text_value(&open.text, lines)
    };
    let node = Node {
        line: open.line,
        tag: open.type_id,
        value,
    };
    match stack.last_mut() {
        Some(parent) => parent.children.push((open.name, node)),
        None => *root = Some(node),
    }
    Ok(())
}

/// Quoted text (OpenCV quotes text with spaces) is one value; else one value per word, each at
/// its own line.
fn text_value(pieces: &[(usize, String)], lines: &LineIndex) -> Value {
    let joined: String = pieces.iter().map(|(_, t)| t.as_str()).collect();
    let trimmed = joined.trim();
    if trimmed.len() >= 2 && trimmed.starts_with('"') && trimmed.ends_with('"') {
        return Value::Scalar(trimmed[1..trimmed.len() - 1].to_string());
    }
    let mut words = Vec::new();
    for (offset, piece) in pieces {
        let mut at = 0;
        for word in piece.split_whitespace() {
            let start = at + piece[at..].find(word).unwrap_or(0);
            at = start + word.len();
            words.push(Node::new(
                lines.line(offset + start),
                Value::Scalar(word.to_string()),
            ));
        }
    }
    match words.len() {
        1 => Value::Scalar(trimmed.to_string()),
        _ => Value::Seq(words),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const OPENCV_XML: &str = "<?xml version=\"1.0\"?>\n<opencv_storage>\n<image_width>640</image_width>\n\
        <calibration_time>\"Tue 03 Jun\"</calibration_time>\n<camera_matrix type_id=\"opencv-matrix\">\n  \
        <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n    5.0e+02 0. 3.2e+02 0. 5.0e+02\n    \
        2.4e+02 0. 0. 1.</data></camera_matrix>\n<empty/>\n</opencv_storage>\n";

    #[test]
    fn reads_opencv_xml_with_lines() {
        let doc = parse(OPENCV_XML).unwrap();
        assert_eq!(doc.get("image_width").unwrap().value, Value::Scalar("640".into()));
        assert_eq!(
            doc.get("calibration_time").unwrap().value,
            Value::Scalar("Tue 03 Jun".into())
        );
        let k = doc.get("camera_matrix").unwrap();
        assert_eq!((k.line, k.tag.as_deref()), (5, Some("opencv-matrix")));
        let Value::Seq(data) = &k.get("data").unwrap().value else {
            panic!("{k:?}")
        };
        assert_eq!(data.len(), 9);
        assert_eq!((data[0].line, data[4].line, data[5].line), (10, 10, 11));
        assert_eq!(doc.get("empty").unwrap().value, Value::Empty);
    }

    #[test]
    fn refuses_broken_files_with_the_line() {
        let truncated = &OPENCV_XML[..OPENCV_XML.find("2.4e+02").unwrap()];
        let e = parse(truncated).unwrap_err();
        assert!(
            e.message.contains("ends inside `<data>` (opened on line 9)"),
            "{e:?}"
        );
        let e = parse("<?xml version=\"1.0\"?>\n<storage>\n</storage>\n").unwrap_err();
        assert!(e.message.contains("not OpenCV's `<opencv_storage>`"), "{e:?}");
        let e = parse("<opencv_storage>\n<a>1</a>\n<a>2</a>\n</opencv_storage>\n").unwrap_err();
        assert_eq!((e.line, e.message.contains("appears twice")), (3, true), "{e:?}");
        let e = parse("<opencv_storage>\n<a>1</b>\n</opencv_storage>\n").unwrap_err();
        assert!(e.message.contains("not well-formed"), "{e:?}");
        let deep = "<a>".repeat(40);
        let e = parse(&format!("<opencv_storage>{deep}")).unwrap_err();
        assert!(e.message.contains("nested deeper"), "{e:?}");
    }
}

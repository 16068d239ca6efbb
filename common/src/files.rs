//! Reading a file whose size is bounded before anything is allocated for it: the one definition
//! every reader of a file the user hands deckwatch goes through (security issue 72, item 5).
//!
//! The file's size from its metadata is checked first, so a sparse 10 GB file is refused
//! without a byte read; the read itself is bounded again, because a file may grow while it is
//! read, or be a pipe or a device whose metadata says 0. A streamed reader ([`open_bounded`])
//! can also bound its lines, so a CSV parser never holds one line of gigabytes. Each reader
//! chooses its bound (a size no legitimate file of its kind reaches) and says why beside it.

use std::fmt;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};

/// A file that could not be read within its bounds: which, and why. Shown as
/// `PATH[:LINE]: PROBLEM`; a caller whose own error names the file takes [`Self::line`] and
/// [`Self::problem`] instead.
#[derive(Debug)]
pub enum FileReadError {
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Larger than the reader accepts. `size_bytes` is the file's size, or, for a file that grew
    /// while it was read (or a pipe), the bytes read when the limit was passed.
    TooLarge {
        path: PathBuf,
        size_bytes: u64,
        max_bytes: u64,
    },
    /// A line (counted from 1) longer than the reader accepts.
    LineTooLong {
        path: PathBuf,
        line: u64,
        max_line_bytes: u64,
    },
    /// Text that is not UTF-8, from its line (counted from 1).
    NotUtf8 {
        path: PathBuf,
        line: u64,
    },
}

impl FileReadError {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            Self::Io { path, .. }
            | Self::TooLarge { path, .. }
            | Self::LineTooLong { path, .. }
            | Self::NotUtf8 { path, .. } => path,
        }
    }

    /// The line (from 1) the error is at, when it is at one.
    pub fn line(&self) -> Option<u64> {
        match self {
            Self::LineTooLong { line, .. } | Self::NotUtf8 { line, .. } => Some(*line),
            Self::Io { .. } | Self::TooLarge { .. } => None,
        }
    }

    /// What is wrong, without the file's name and line.
    pub fn problem(&self) -> String {
        match self {
            Self::Io { source, .. } => format!("cannot read: {source}"),
            Self::TooLarge {
                size_bytes,
                max_bytes,
                ..
            } => format!(
                "{}, more than the {} deckwatch reads from such a file",
                Bytes(*size_bytes),
                Bytes(*max_bytes)
            ),
            Self::LineTooLong { max_line_bytes, .. } => format!(
                "a line longer than {}, the most deckwatch reads from such a file",
                Bytes(*max_line_bytes)
            ),
            Self::NotUtf8 { .. } => "not UTF-8 text".to_string(),
        }
    }

    /// The error of reading `path`: the bound a [`BoundedFile`] reported through `std::io`
    /// comes back as itself, anything else is an I/O error.
    fn from_io(path: &Path, e: std::io::Error) -> Self {
        let io = |source| Self::Io {
            path: path.to_path_buf(),
            source,
        };
        if !e.get_ref().is_some_and(|inner| inner.is::<FileReadError>()) {
            return io(e);
        }
        match e.into_inner().map(|inner| inner.downcast::<FileReadError>()) {
            Some(Ok(bound)) => *bound,
            // Checked to be one above; kept total without a panic.
            _ => io(std::io::Error::other("a bounded read failed")),
        }
    }
}

impl fmt::Display for FileReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path().display())?;
        if let Some(line) = self.line() {
            write!(f, ":{line}")?;
        }
        write!(f, ": {}", self.problem())
    }
}

impl std::error::Error for FileReadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

/// A byte count as a person reads it: bytes, and MiB when it is that large.
struct Bytes(u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const MIB: u64 = 1 << 20;
        if self.0 >= MIB {
            write!(f, "{} bytes ({:.1} MiB)", self.0, self.0 as f64 / MIB as f64)
        } else {
            write!(f, "{} bytes", self.0)
        }
    }
}

/// A file open for reading whose total bytes (and optionally its line lengths) are bounded: a
/// read past a bound is an `std::io::Error` carrying the [`FileReadError`] (so a CSV or PNG
/// decoder reading through it reports it), and nothing beyond the bound is read.
pub struct BoundedFile {
    path: PathBuf,
    /// One byte beyond the limit is let through, to tell "exactly the limit" from "more".
    file: std::io::Take<File>,
    /// Its size when it was opened (0 for a pipe or a device).
    size_bytes: u64,
    max_bytes: u64,
    read_bytes: u64,
    max_line_bytes: Option<u64>,
    /// Bytes since the last newline, and that line's number (from 1).
    line_bytes: u64,
    line: u64,
    /// A bound was passed and reported: the file ends there (a caller that skips bad rows and
    /// reads on gets the end, not the same error forever).
    ended_at_bound: bool,
}

/// Opens `path` for a streamed read of at most `max_bytes`: a larger regular file is refused
/// here, from its metadata, before anything is read.
pub fn open_bounded(path: &Path, max_bytes: u64) -> Result<BoundedFile, FileReadError> {
    let io = |source| FileReadError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io)?;
    let size_bytes = file.metadata().map_err(io)?.len();
    if size_bytes > max_bytes {
        return Err(FileReadError::TooLarge {
            path: path.to_path_buf(),
            size_bytes,
            max_bytes,
        });
    }
    Ok(BoundedFile {
        path: path.to_path_buf(),
        file: file.take(max_bytes.saturating_add(1)),
        size_bytes,
        max_bytes,
        read_bytes: 0,
        max_line_bytes: None,
        line_bytes: 0,
        line: 1,
        ended_at_bound: false,
    })
}

impl BoundedFile {
    /// Also bounds each line (the bytes between two newlines, the newline not counted).
    pub fn with_max_line_bytes(mut self, max_line_bytes: u64) -> Self {
        self.max_line_bytes = Some(max_line_bytes);
        self
    }

    /// The file being read.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The open file's metadata: its owner and mode checked on the file read, not on a name
    /// that could be swapped in between (the signing key, the kept signing state).
    pub fn metadata(&self) -> std::io::Result<std::fs::Metadata> {
        self.file.get_ref().metadata()
    }

    fn bound_error(&mut self, e: FileReadError) -> std::io::Error {
        self.ended_at_bound = true;
        std::io::Error::new(std::io::ErrorKind::InvalidData, e)
    }

    /// Counts the lines of bytes just read; an error at the first line past its bound.
    fn check_lines(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        let Some(max_line_bytes) = self.max_line_bytes else {
            return Ok(());
        };
        for segment in bytes.split_inclusive(|&b| b == b'\n') {
            let ends_line = segment.last() == Some(&b'\n');
            self.line_bytes += (segment.len() - usize::from(ends_line)) as u64;
            if self.line_bytes > max_line_bytes {
                let e = FileReadError::LineTooLong {
                    path: self.path.clone(),
                    line: self.line,
                    max_line_bytes,
                };
                return Err(self.bound_error(e));
            }
            if ends_line {
                self.line += 1;
                self.line_bytes = 0;
            }
        }
        Ok(())
    }
}

impl Read for BoundedFile {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.ended_at_bound {
            return Ok(0);
        }
        let n = self.file.read(buf)?;
        self.read_bytes += n as u64;
        if self.read_bytes > self.max_bytes {
            let e = FileReadError::TooLarge {
                path: self.path.clone(),
                size_bytes: self.read_bytes,
                max_bytes: self.max_bytes,
            };
            return Err(self.bound_error(e));
        }
        self.check_lines(&buf[..n])?;
        Ok(n)
    }
}

/// The whole of `path`, at most `max_bytes`: a larger file is refused from its size before
/// anything is read or allocated, and the read stops one byte past the limit.
pub fn read_bounded(path: &Path, max_bytes: u64) -> Result<Vec<u8>, FileReadError> {
    let mut file = open_bounded(path, max_bytes)?;
    // The size was checked against the limit: reserving it is reserving at most the limit.
    let mut bytes = Vec::with_capacity(file.size_bytes as usize);
    file.read_to_end(&mut bytes)
        .map_err(|e| FileReadError::from_io(path, e))?;
    Ok(bytes)
}

/// [`read_bounded`] as UTF-8 text; text that is not is an error naming its line.
pub fn read_bounded_to_string(path: &Path, max_bytes: u64) -> Result<String, FileReadError> {
    String::from_utf8(read_bounded(path, max_bytes)?).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        FileReadError::NotUtf8 {
            path: path.to_path_buf(),
            line: 1 + valid.iter().filter(|&&b| b == b'\n').count() as u64,
        }
    })
}

/// The bound a read through a [`BoundedFile`] passed, when that is what `e` is.
pub fn bound_in(e: &std::io::Error) -> Option<&FileReadError> {
    e.get_ref()
        .and_then(|inner| inner.downcast_ref::<FileReadError>())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    const GIB: u64 = 1 << 30;

    /// A sparse 10 GiB file: no disk blocks, nothing to read if the size is checked first.
    fn sparse(dir: &Path, name: &str, size_bytes: u64) -> PathBuf {
        let path = dir.join(name);
        File::create(&path).unwrap().set_len(size_bytes).unwrap();
        path
    }

    #[test]
    fn a_sparse_file_beyond_the_limit_is_refused_from_its_size() {
        let dir = tempfile::tempdir().unwrap();
        let path = sparse(dir.path(), "huge.toml", 10 * GIB);
        for e in [
            read_bounded(&path, 1 << 20).unwrap_err(),
            read_bounded_to_string(&path, 1 << 20).unwrap_err(),
            open_bounded(&path, 1 << 20).err().unwrap(),
        ] {
            // The exact size: it came from the metadata, not from reading up to the limit.
            assert!(
                matches!(e, FileReadError::TooLarge { size_bytes, max_bytes, .. }
                    if size_bytes == 10 * GIB && max_bytes == 1 << 20),
                "{e:?}"
            );
            let text = e.to_string();
            assert!(text.contains("huge.toml"), "{text}");
            assert!(
                text.contains("10737418240 bytes") && text.contains("1048576 bytes"),
                "{text}"
            );
            assert_eq!(e.path(), path);
        }
    }

    #[test]
    fn a_file_within_the_limit_is_read_whole() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.csv");
        std::fs::write(&path, "a,b\n1,2\n").unwrap();
        assert_eq!(read_bounded(&path, 8).unwrap(), b"a,b\n1,2\n");
        assert_eq!(read_bounded_to_string(&path, 8).unwrap(), "a,b\n1,2\n");
        let e = read_bounded(&path, 7).unwrap_err();
        assert!(matches!(
            e,
            FileReadError::TooLarge {
                size_bytes: 8,
                max_bytes: 7,
                ..
            }
        ));
    }

    /// A device whose metadata says 0 bytes is stopped by the bounded read, one byte past.
    #[test]
    fn an_endless_device_is_stopped_at_the_limit() {
        let e = read_bounded(Path::new("/dev/zero"), 1000).unwrap_err();
        assert!(
            matches!(
                e,
                FileReadError::TooLarge {
                    size_bytes: 1001,
                    max_bytes: 1000,
                    ..
                }
            ),
            "{e:?}"
        );
        let mut streamed = Vec::new();
        let mut file = open_bounded(Path::new("/dev/zero"), 1000).unwrap();
        let e = file.read_to_end(&mut streamed).unwrap_err();
        assert!(streamed.len() <= 1001);
        // Reported once; then the file ends, for a caller that reads on past a bad row.
        assert_eq!(file.read(&mut [0u8; 16]).unwrap(), 0);
        let bound = bound_in(&e).expect("the bound travels through std::io");
        assert!(matches!(bound, FileReadError::TooLarge { max_bytes: 1000, .. }));
        assert!(e.to_string().contains("/dev/zero"), "{e}");
    }

    #[test]
    fn a_streamed_line_beyond_its_bound_names_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frames.csv");
        let mut f = File::create(&path).unwrap();
        writeln!(f, "index,timestamp_ns").unwrap();
        writeln!(f, "0,{}", "9".repeat(100)).unwrap();
        drop(f);
        let mut text = String::new();
        open_bounded(&path, 1 << 20)
            .unwrap()
            .with_max_line_bytes(102)
            .read_to_string(&mut text)
            .unwrap();
        let e = open_bounded(&path, 1 << 20)
            .unwrap()
            .with_max_line_bytes(101)
            .read_to_string(&mut String::new())
            .unwrap_err();
        let bound = bound_in(&e).unwrap();
        assert!(
            matches!(
                bound,
                FileReadError::LineTooLong {
                    line: 2,
                    max_line_bytes: 101,
                    ..
                }
            ),
            "{bound:?}"
        );
    }

    #[test]
    fn text_that_is_not_utf8_names_its_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.csv");
        std::fs::write(&path, b"time_s\n1\n\xff\n").unwrap();
        let e = read_bounded_to_string(&path, 100).unwrap_err();
        assert!(matches!(e, FileReadError::NotUtf8 { line: 3, .. }), "{e:?}");
    }
}

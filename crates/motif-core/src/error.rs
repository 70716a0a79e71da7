//! The error type of the geometry core.
//!
//! Every error says which file (when there is one), where in it (line or byte offset), and what is
//! wrong, so the CLI can print it once and exit with code 2 for bad input.

use std::fmt;
use std::path::PathBuf;

/// Where in an input file a problem was found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Position {
    /// 1-based line number in a text file.
    Line(usize),
    /// 0-based byte offset in a binary file.
    Byte(u64),
    /// The problem concerns the file as a whole (e.g. it is empty).
    Whole,
}

impl Position {
    /// `"line 3: "`, `"byte 40: "`, or nothing for the whole file (whose message names it).
    pub fn prefix(&self) -> String {
        match self {
            Position::Whole => String::new(),
            p => format!("{p}: "),
        }
    }
}

impl fmt::Display for Position {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Position::Line(l) => write!(f, "line {l}"),
            Position::Byte(b) => write!(f, "byte {b}"),
            Position::Whole => write!(f, "file"),
        }
    }
}

/// Errors of the geometry core.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused to read or write a file.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file's content is malformed: truncated, wrong magic, indices out of range, NaN, ...
    #[error("{path}: {}{message}", position.prefix())]
    Parse {
        /// The file concerned.
        path: PathBuf,
        /// Where the problem is.
        position: Position,
        /// What is wrong, in words a user can act on.
        message: String,
    },
    /// The file name's extension names no format Motif reads or writes.
    #[error(
        "{path}: {} (Motif reads and writes .obj, .ply, .off, .stl, .gltf/.glb)",
        if extension.is_empty() {
            "no file extension to choose the format by".to_string()
        } else {
            format!("unsupported format {extension:?}")
        }
    )]
    UnsupportedFormat {
        /// The file concerned.
        path: PathBuf,
        /// The extension found (may be empty).
        extension: String,
    },
    /// An algorithm was given input it cannot work with (empty mesh, too few points, ...).
    #[error("{0}")]
    InvalidInput(String),
    /// An option is out of its valid range.
    #[error("invalid option {name}: {message}")]
    InvalidOption {
        /// The option's name as the user knows it.
        name: &'static str,
        /// What is wrong and what range is valid.
        message: String,
    },
}

impl Error {
    /// Builds a [`Error::Parse`].
    pub fn parse(path: impl Into<PathBuf>, position: Position, message: impl Into<String>) -> Self {
        Error::Parse { path: path.into(), position, message: message.into() }
    }

    /// Builds an [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io { path: path.into(), source }
    }

    /// True when the error is the user's input (bad file, bad option), as opposed to a failure of
    /// the system; the CLI exits with code 2 for these and 1 otherwise.
    pub fn is_bad_input(&self) -> bool {
        match self {
            Error::Io { source, .. } => matches!(
                source.kind(),
                std::io::ErrorKind::NotFound
                    | std::io::ErrorKind::InvalidData
                    | std::io::ErrorKind::UnexpectedEof
                    | std::io::ErrorKind::IsADirectory
            ),
            _ => true,
        }
    }
}

/// Result alias of the geometry core.
pub type Result<T, E = Error> = std::result::Result<T, E>;

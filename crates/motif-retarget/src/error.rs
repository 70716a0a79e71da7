//! The error type of the retargeting crate.
//!
//! Every message says what is wrong and where (which field of an `mrf_grid_v1` file, which site,
//! edge or label of an energy), so the CLI can print it once and exit with code 2 for bad input.

use std::path::PathBuf;

/// Errors of the retargeting crate.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused to read a file.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The input is not well-formed JSON.
    #[error("invalid JSON: {message}")]
    Json {
        /// The parser's message, with line and column.
        message: String,
    },
    /// A field of an `mrf_grid_v1` problem is missing, has the wrong type, or is inconsistent with
    /// the other fields.
    #[error("mrf_grid_v1 field `{field}`: {message}")]
    Field {
        /// The field's name, with an index where one element is at fault (`unary[12]`).
        field: String,
        /// What is wrong, in words a user can act on.
        message: String,
    },
    /// An energy passed to alpha-expansion is malformed (edge out of range, wrong label count, ...).
    #[error("invalid MRF energy: {message}")]
    InvalidEnergy {
        /// What is wrong.
        message: String,
    },
    /// A cost callback returned NaN or minus infinity, which no labelling can be compared with.
    #[error(
        "{term} cost is {value} at {location}; costs must be numbers or +infinity (use +infinity or a \
         large finite value for forbidden labels)"
    )]
    NonFiniteCost {
        /// `"unary"` or `"pairwise"`.
        term: &'static str,
        /// The offending value, printed.
        value: String,
        /// The site(s) and label(s) concerned, in words.
        location: String,
    },
}

/// Result alias of the retargeting crate.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// A [`Error::Field`] error.
    pub(crate) fn field(field: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Field { field: field.into(), message: message.into() }
    }

    /// An [`Error::InvalidEnergy`] error.
    pub(crate) fn energy(message: impl Into<String>) -> Self {
        Error::InvalidEnergy { message: message.into() }
    }
}

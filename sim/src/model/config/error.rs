//! Configuration errors ([`ConfigError`]) and the helpers that build them: a value out of its
//! range, and a memory-system error named by its `memory.` key.

use std::fmt;
use std::path::PathBuf;

use crate::model::memory::MemConfigError;

/// A configuration could not be read, parsed, or holds an invalid value. Every variant names
/// the file, override or key concerned.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// The configuration file could not be read.
    #[error("cannot read config file {}: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The operating system's reason.
        reason: String,
    },
    /// The configuration file is not valid TOML.
    #[error("config file {} is not valid TOML: {message}", path.display())]
    Syntax {
        /// The file.
        path: PathBuf,
        /// The parser's message (with line, column and an excerpt).
        message: String,
    },
    /// A `--set` argument is not of the form `key=value`.
    #[error("--set `{text}`: {reason}")]
    Override {
        /// The argument as given.
        text: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A key or section the configuration does not have.
    #[error("{origin}: unknown key `{key}`; {hint}")]
    UnknownKey {
        /// Where the key was given: the file or the `--set` argument.
        origin: String,
        /// The dotted key.
        key: String,
        /// The valid keys of its section (and a likely intended key, if any).
        hint: String,
    },
    /// A value of the wrong type for its key, or outside its type's range.
    #[error("{origin}: `{key}` = {value}: {reason}")]
    Type {
        /// Where the value was given: the file or the `--set` argument.
        origin: String,
        /// The dotted key.
        key: String,
        /// The value as TOML.
        value: String,
        /// The expected type.
        reason: String,
    },
    /// A value is out of range or inconsistent with another (found by
    /// [`SimConfig::validate`](super::SimConfig::validate)).
    #[error("invalid configuration: {key} = {value}: {reason}")]
    Invalid {
        /// The dotted key.
        key: String,
        /// Its value.
        value: String,
        /// Why it is rejected.
        reason: String,
    },
    /// The configuration could not be converted to or from a TOML table (a value outside
    /// TOML's integer range, or a section missing from the merged table).
    #[error("configuration TOML conversion failed: {0}")]
    Toml(String),
}

impl ConfigError {
    /// The dotted key the error is about, when it is about one key.
    pub fn key(&self) -> Option<&str> {
        match self {
            ConfigError::UnknownKey { key, .. }
            | ConfigError::Type { key, .. }
            | ConfigError::Invalid { key, .. } => Some(key),
            ConfigError::Read { .. }
            | ConfigError::Syntax { .. }
            | ConfigError::Override { .. }
            | ConfigError::Toml(_) => None,
        }
    }
}

/// An [`ConfigError::Invalid`] for `key` = `value`.
pub(super) fn invalid(
    key: &str,
    value: impl fmt::Display,
    reason: impl Into<String>,
) -> ConfigError {
    ConfigError::Invalid {
        key: key.to_string(),
        value: value.to_string(),
        reason: reason.into(),
    }
}

/// Checks that `value` of `key` lies in `range`.
pub(super) fn in_range<T>(
    key: &str,
    value: T,
    range: std::ops::RangeInclusive<T>,
) -> Result<(), ConfigError>
where
    T: PartialOrd + fmt::Display + Copy,
{
    if range.contains(&value) {
        Ok(())
    } else {
        Err(invalid(
            key,
            value,
            format!("must be {}..={}", range.start(), range.end()),
        ))
    }
}

/// A [`MemConfig`](crate::model::memory::MemConfig) validation error as an
/// [`ConfigError::Invalid`] naming its `memory.` key.
pub(super) fn memory_error(e: MemConfigError) -> ConfigError {
    let (key, value) = match &e {
        MemConfigError::Zero { key } => (*key, 0),
        MemConfigError::NotPowerOfTwo { key, value }
        | MemConfigError::TooLarge { key, value, .. } => (*key, *value),
        MemConfigError::SectorVsLine { sector, .. } => ("sector_bytes", *sector),
        MemConfigError::SmallerThanLine { key, bytes, .. } => (*key, *bytes),
        MemConfigError::WaysDoNotDivide { key, ways, .. } => (*key, *ways),
        MemConfigError::RayWays { ray_ways, .. } => ("l2_ray_ways", *ray_ways),
        MemConfigError::NoSms => return invalid("gpu.sms", 0, e.to_string()),
        MemConfigError::DramShare { num, den } => {
            return invalid(
                "memory.dram_share",
                format!("[{num}, {den}]"),
                e.to_string(),
            )
        }
    };
    invalid(&format!("memory.{key}"), value, e.to_string())
}

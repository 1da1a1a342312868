//! The error type of every fallible `vtq-gen` operation.

/// Why generating, simulating, synthesizing or linting failed.
#[derive(Debug, thiserror::Error)]
pub enum GenError {
    /// An external tool (iverilog, vvp, verilator, yosys) is not on `PATH`; the message names
    /// the Debian package that provides it.
    #[error(
        "{tool} is not installed (not found on PATH; Debian package `{}`)",
        crate::tools::debian_package(tool)
    )]
    ToolMissing {
        /// Executable name.
        tool: String,
    },
    /// Reading or writing a file, or starting a process, failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done, naming the file or command.
        context: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A tool ran but reported failure (syntax error, elaboration error, ...).
    #[error("{tool} failed ({status}):\n{output}")]
    ToolFailed {
        /// Executable name.
        tool: String,
        /// Exit status as text.
        status: String,
        /// The tool's standard output and error (the end of it, if long).
        output: String,
    },
    /// A tool's output did not have the expected shape.
    #[error("could not understand the output of {tool}: {reason}")]
    Parse {
        /// Executable name.
        tool: String,
        /// What was missing or malformed.
        reason: String,
    },
    /// A block description cannot be turned into Verilog.
    #[error("block description `{block}` is invalid: {reason}")]
    InvalidDesc {
        /// Module name of the block.
        block: String,
        /// The problem, naming the offending item.
        reason: String,
    },
    /// A co-simulation could not be set up (signal names or widths disagree, no cycles, ...).
    #[error("co-simulation of `{block}`: {reason}")]
    Cosim {
        /// Module name of the block.
        block: String,
        /// The problem.
        reason: String,
    },
    /// The hardware configuration is out of range.
    #[error(transparent)]
    Config(#[from] vtq_hdl::ConfigError),
    /// An RT-unit parameter or configuration is out of range.
    #[error(transparent)]
    RtUnit(#[from] vtq_hdl::rt_unit::RtUnitError),
    /// An area-model parameter is out of range.
    #[error("invalid area parameter: {key} = {value}: {reason}")]
    AreaParam {
        /// The offending parameter.
        key: &'static str,
        /// Its value.
        value: u64,
        /// Why it is rejected.
        reason: String,
    },
}

impl GenError {
    /// Whether this error only says that an external tool is not installed.
    pub fn is_tool_missing(&self) -> bool {
        matches!(self, GenError::ToolMissing { .. })
    }

    /// Shorthand for an [`GenError::Io`] with context.
    pub(crate) fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        GenError::Io {
            context: context.into(),
            source,
        }
    }
}

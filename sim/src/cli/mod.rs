//! The `vtq` command line, listed bottom-up: the checks and fallbacks of its output files and
//! the writers of images and time series, the fuzzing of the parsers of user input, then the
//! commands.

// Files the commands read and write.
pub mod image;
pub mod output;
pub mod time_series;

// Fuzzing of the parsers of user input.
pub mod fuzz;

// One module per command.
pub mod cmd;

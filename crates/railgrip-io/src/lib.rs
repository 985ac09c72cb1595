//! The files railgrip reads and writes, under two rules every crate of the workspace follows:
//!
//! - [`input`]: a file a user or a log names is read only if it is a regular file (a FIFO would
//!   block, a device would never end) and never beyond a size limit for its kind.
//! - [`atomic`]: an output is written to a temporary file beside its final name and renamed
//!   over it, so a crash never leaves a half-written model or table that looks complete.

pub mod atomic;
pub mod input;

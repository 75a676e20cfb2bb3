//! Compensating the play: the backlash inverse with its direction memory ([`inverse`]), and the adaptive loop
//! that feeds it the on-line estimates and inverts the linear block ([`adaptive`]). Plain Rust on numbers
//! and parameter structs: the FMU (`fmus::compensator`), the command line and the Python package drive the
//! same functions.

pub mod adaptive;
pub mod inverse;

pub use inverse::{Answer, BacklashInverse, Degenerate, Direction, chattering};

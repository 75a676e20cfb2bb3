//! What a diagnosis tells: the Markdown report with its figures ([`markdown`]) and the contract's typed JSON
//! object ([`output`]).

pub mod markdown;
pub mod output;

pub use markdown::{ReportError, ReportInput, Validation, write_report};

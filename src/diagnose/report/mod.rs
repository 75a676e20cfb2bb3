//! What a diagnosis tells: the Markdown report ([`markdown`]) with its figures ([`figures`]; the evidence
//! figure is the chosen effect's own), what it is written from ([`input`]), and the contract's typed JSON
//! object ([`output`]).

pub mod figures;
pub mod input;
pub mod markdown;
pub mod output;
pub mod play;

pub use figures::ReportFigure;
pub use input::{ReportError, ReportInput, Validation};
pub use markdown::write_report;

//! Diagnosis: from a fitted model's residual to the effects the model lacks, in rooms by job.
//!
//! - [`effects`]: the open catalogue, one module per effect behind one trait, registered in one list.
//! - [`search`]: the loop (engine and decision rule).
//! - [`fit`]: models, problems, starts, structure selection and the Levenberg-Marquardt fitter.
//! - [`residual`]: the residual tests and the statistics they and the decision use.
//! - [`report`]: the Markdown report with its figures and the typed JSON output.
//! - [`bench`](mod@bench): simulated test-bench records with known effects (tests and measurements).
//! - [`record`]: decimation of densely sampled records.
//!
//! Rooms depend one way: `residual` and `fit` know no effect; `effects` uses them; `search` uses the
//! catalogue only through its trait; `report` comes last.

pub mod bench;
pub mod effects;
pub mod fit;
pub mod id;
pub mod record;
pub mod report;
pub mod residual;
pub mod search;

/// Structure selection, as the command line and the Python binding name it.
pub use fit::structure;
/// The JSON output, as the library's API names it.
pub use report::output;
/// The engine, as the command line and the Python binding name it.
pub use search::engine;

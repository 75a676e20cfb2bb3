//! What a model must provide to be served as an FMU, in either FMI version.

use super::vars::{Value, VarInfo};
use serde::{Serialize, de::DeserializeOwned};

/// A discrete-time model behind an FMU.
///
/// The core guarantees, before it calls [`Model::set`]: the variable exists, has the value's type, may be
/// set in the current state (inputs always; fixed parameters only before initialization mode is left), and
/// a Real is finite and within the XML's min and max. The model checks what the table cannot express (for
/// example consistency between parameters) in [`Model::exit_initialization`].
pub trait Model: Serialize + DeserializeOwned + Send + 'static {
    /// The generated per-variable enum.
    type Var: Copy;
    const MODEL_IDENTIFIER: &'static str;
    const GUID: &'static str;
    const LOG_CATEGORIES: &'static [&'static str];
    /// The generated variable table; `Self::var(i)` is the variant of `VARIABLES[i]`.
    const VARIABLES: &'static [VarInfo];
    /// Most samples one communication step may advance; a step reaching more sample instants is cut at the
    /// last allowed one and answered with Discard.
    const MAX_SAMPLES_PER_STEP: u64;

    fn var(index: usize) -> Self::Var;
    /// A model with every variable at its start value (the core applies the XML start values next).
    fn new() -> Self;
    fn get(&self, var: Self::Var) -> Value;
    fn set(&mut self, var: Self::Var, value: Value);
    /// Validate the parameters and prepare the model for stepping. `Err` names the parameter and the reason.
    fn exit_initialization(&mut self) -> Result<(), String>;
    /// Sample period in seconds (a parameter): the core samples at start + k Ts (see
    /// [`LayerState`](super::timing::LayerState)).
    fn sample_period(&self) -> f64;
    /// Advance `n` samples with the inputs as they are now (the core sets the latched ones first).
    fn step(&mut self, n: u64) -> Result<(), String>;
    /// A condition of the inputs as set that the model answers with a documented fallback instead of refusing
    /// (a degenerate estimate): the core answers the get or step that meets it with Warning and logs the text
    /// under logStatusWarning. None (the default): nothing to report.
    fn warning(&self) -> Option<String> {
        None
    }

    /// Samples the model has processed since initialization mode was left; None before (not initialised).
    /// A restored state's count must be the layer's.
    fn samples(&self) -> Option<u64>;
    /// Consistency of a model restored from an FMU state (which may come from outside: a file, another
    /// process). `Err` names what is wrong; the state is then refused.
    fn check_restored(&self) -> Result<(), String>;
}

//! One FMI 2.0 co-simulation layer for any model.
//!
//! This module knows the protocol and nothing of physics: the 34 exported functions ([`exports`]), the state
//! machine of the standard's co-simulation calling-sequence table ([`state`]), argument checks, logging and
//! FMU state (de)serialisation ([`instance`]). A model plugs in through the [`Model`] trait; the two FMUs of
//! this crate are small adapters in `crate::fmus`.
//!
//! One shared library serves both FMUs: `fmi2Instantiate` picks the model whose GUID the importer passes
//! from those registered in `crate::FMUS` ([`registry`]).
//!
//! The FMI 3.0 layer (`crate::fmi3`) serves the same models through the same core: the [`Model`] trait,
//! the [`instance::Instance`] (timing, argument checks, FMU state, logging) and the [`registry`]; what is
//! FMI 2.0 only here is [`exports`], [`ffi`] and the call table of [`state`].

pub mod boundary;
pub mod ffi;
pub mod instance;
pub mod registry;
pub mod state;
pub mod vars;

pub mod exports;

use serde::{Serialize, de::DeserializeOwned};
use vars::{Value, VarInfo};

/// A discrete-time model behind an FMU.
///
/// The layer guarantees, before it calls [`Model::set`]: the variable exists, has the value's type, may be
/// set in the current state (inputs always; fixed parameters only before `fmi2ExitInitializationMode`), and a
/// Real is finite and within the XML's min and max. The model checks what the table cannot express (for
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
    /// last allowed one and answered with fmi2Discard.
    const MAX_SAMPLES_PER_STEP: u64;

    fn var(index: usize) -> Self::Var;
    /// A model with every variable at its start value (the layer applies the XML start values next).
    fn new() -> Self;
    fn get(&self, var: Self::Var) -> Value;
    fn set(&mut self, var: Self::Var, value: Value);
    /// Validate the parameters and prepare the model for stepping. `Err` names the parameter and the reason.
    fn exit_initialization(&mut self) -> Result<(), String>;
    /// Sample period in seconds (a parameter): the layer samples at start + k Ts (see `instance::LayerState`).
    fn sample_period(&self) -> f64;
    /// Advance `n` samples with the inputs as they are now (the layer sets the latched ones first).
    fn step(&mut self, n: u64) -> Result<(), String>;
    /// Consistency of a model restored from an FMU state (which may come from outside: a file, another
    /// process). `Err` names what is wrong; the state is then refused.
    fn check_restored(&self) -> Result<(), String>;
}

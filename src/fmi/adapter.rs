//! The object-safe face of a [`Model`], so that one instance type serves every FMU.

use super::fmu_state;
use super::model::Model;
use super::timing::LayerState;
use super::vars::{Start, Value, VarInfo};

/// A model as the instance drives it, by variable index (see [`Model`] for what each function promises).
pub trait Slave: Send {
    fn identifier(&self) -> &'static str;
    fn guid(&self) -> &'static str;
    fn log_categories(&self) -> &'static [&'static str];
    fn variables(&self) -> &'static [VarInfo];
    /// Most samples one communication step may advance; a step reaching more instants is cut there.
    fn max_samples_per_step(&self) -> u64;
    fn get(&self, index: usize) -> Value;
    fn set(&mut self, index: usize, value: Value);
    fn exit_initialization(&mut self) -> Result<(), String>;
    fn sample_period(&self) -> f64;
    fn step(&mut self, n: u64) -> Result<(), String>;
    /// See [`Model::warning`].
    fn warning(&self) -> Option<String>;
    /// A fresh model at its start values.
    fn reset(&mut self);
    fn save(&self, layer: &LayerState) -> Result<Vec<u8>, String>;
    fn restore(&mut self, bytes: &[u8]) -> Result<LayerState, String>;
    /// Check that `bytes` is a state of this model without applying it.
    fn check_state(&self, bytes: &[u8]) -> Result<(), String>;
}

/// The generic adapter from [`Model`] to [`Slave`].
pub struct Adapter<M: Model>(pub M);

/// A model at its XML start values.
fn fresh<M: Model>() -> M {
    let mut m = M::new();
    for (i, v) in M::VARIABLES.iter().enumerate() {
        let value = match v.start {
            Start::None => continue,
            Start::Real(x) => Value::Real(x),
            Start::Integer(x) => Value::Integer(x),
            Start::Boolean(x) => Value::Boolean(x),
            Start::String(x) => Value::String(x.to_string()),
        };
        m.set(M::var(i), value);
    }
    m
}

impl<M: Model> Adapter<M> {
    pub fn new() -> Self {
        Self(fresh::<M>())
    }
}

impl<M: Model> Default for Adapter<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: Model> Slave for Adapter<M> {
    fn identifier(&self) -> &'static str {
        M::MODEL_IDENTIFIER
    }
    fn guid(&self) -> &'static str {
        M::GUID
    }
    fn log_categories(&self) -> &'static [&'static str] {
        M::LOG_CATEGORIES
    }
    fn variables(&self) -> &'static [VarInfo] {
        M::VARIABLES
    }
    fn max_samples_per_step(&self) -> u64 {
        M::MAX_SAMPLES_PER_STEP
    }
    fn get(&self, index: usize) -> Value {
        self.0.get(M::var(index))
    }
    fn set(&mut self, index: usize, value: Value) {
        self.0.set(M::var(index), value)
    }
    fn exit_initialization(&mut self) -> Result<(), String> {
        self.0.exit_initialization()
    }
    fn sample_period(&self) -> f64 {
        self.0.sample_period()
    }
    fn step(&mut self, n: u64) -> Result<(), String> {
        self.0.step(n)
    }
    fn warning(&self) -> Option<String> {
        self.0.warning()
    }
    fn reset(&mut self) {
        self.0 = fresh::<M>();
    }
    fn save(&self, layer: &LayerState) -> Result<Vec<u8>, String> {
        fmu_state::save(&self.0, layer)
    }
    fn restore(&mut self, bytes: &[u8]) -> Result<LayerState, String> {
        let (layer, model) = fmu_state::parse::<M>(bytes)?;
        self.0 = model;
        Ok(layer)
    }
    fn check_state(&self, bytes: &[u8]) -> Result<(), String> {
        fmu_state::parse::<M>(bytes).map(|_| ())
    }
}

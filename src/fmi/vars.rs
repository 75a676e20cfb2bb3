//! The variable table the FMI layer works from; build.rs generates one per model description.

/// The FMI base type of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarType {
    Real,
    Integer,
    Boolean,
    String,
}

impl VarType {
    pub fn name(self) -> &'static str {
        match self {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Boolean => "Boolean",
            VarType::String => "String",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    Parameter,
    Input,
    Output,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variability {
    Fixed,
    Tunable,
    Discrete,
    Continuous,
}

/// A start value from the XML.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Start {
    None,
    Real(f64),
    Integer(i32),
    Boolean(bool),
    String(&'static str),
}

/// One ScalarVariable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VarInfo {
    pub name: &'static str,
    pub vr: u32,
    pub ty: VarType,
    pub causality: Causality,
    pub variability: Variability,
    pub start: Start,
    pub min: Option<f64>,
    pub max: Option<f64>,
}

/// A value crossing the model boundary.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Real(f64),
    Integer(i32),
    Boolean(bool),
    String(String),
}

impl Value {
    pub fn as_real(&self) -> f64 {
        match self {
            Value::Real(v) => *v,
            Value::Integer(v) => *v as f64,
            Value::Boolean(b) => f64::from(u8::from(*b)),
            Value::String(_) => f64::NAN,
        }
    }

    pub fn as_integer(&self) -> i32 {
        match self {
            Value::Integer(v) => *v,
            Value::Real(v) => *v as i32,
            Value::Boolean(b) => i32::from(*b),
            Value::String(_) => 0,
        }
    }

    pub fn as_bool(&self) -> bool {
        match self {
            Value::Boolean(b) => *b,
            Value::Integer(v) => *v != 0,
            Value::Real(v) => *v != 0.0,
            Value::String(s) => !s.is_empty(),
        }
    }
}

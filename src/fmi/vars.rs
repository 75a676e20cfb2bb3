//! The variable table the core works from (build.rs generates one per model description), the checks a
//! value must pass to be set, and the lookup from value reference to variable.

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

/// A value the variable `v` may take: a finite Real or Integer within the XML's min and max.
pub fn check_value(v: &VarInfo, value: &Value) -> Result<(), String> {
    if let Value::Real(x) = value
        && !x.is_finite()
    {
        return Err(format!("'{}' = {x} is not a finite number", v.name));
    }
    let x = value.as_real();
    if matches!(value, Value::Real(_) | Value::Integer(_)) {
        if let Some(lo) = v.min
            && x < lo
        {
            return Err(format!("'{}' = {x} is below its minimum {lo}", v.name));
        }
        if let Some(hi) = v.max
            && x > hi
        {
            return Err(format!("'{}' = {x} is above its maximum {hi}", v.name));
        }
    }
    Ok(())
}

/// Indices of the input variables, in the order of the variable table.
pub fn input_indices(vars: &[VarInfo]) -> Vec<usize> {
    vars.iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Input)
        .map(|(i, _)| i)
        .collect()
}

/// Value reference -> variable index for each of the four types: a dense table when the largest value
/// reference is small (it is: the model descriptions number their variables below 100), so that a lookup is one
/// load instead of a scan of the variable list; a scan otherwise.
pub struct VrTable {
    /// `dense[type][vr]` = index + 1, 0 for none. Empty when the references are too sparse.
    dense: [Vec<u16>; 4],
}

impl VrTable {
    /// Largest value reference put in the dense table.
    const DENSE_MAX: u32 = 4096;

    fn slot(ty: VarType) -> usize {
        match ty {
            VarType::Real => 0,
            VarType::Integer => 1,
            VarType::Boolean => 2,
            VarType::String => 3,
        }
    }

    pub fn new(vars: &[VarInfo]) -> Self {
        let mut dense: [Vec<u16>; 4] = Default::default();
        let fits =
            vars.len() < usize::from(u16::MAX) && vars.iter().all(|v| v.vr <= Self::DENSE_MAX);
        if fits {
            // The first variable with a given (type, vr) wins, as the scan it replaces.
            for (i, v) in vars.iter().enumerate().rev() {
                let t = &mut dense[Self::slot(v.ty)];
                let at = v.vr as usize;
                if t.len() <= at {
                    t.resize(at + 1, 0);
                }
                t[at] = (i + 1) as u16;
            }
        }
        Self { dense }
    }

    pub fn get(&self, vars: &[VarInfo], ty: VarType, vr: u32) -> Option<usize> {
        if self.dense.iter().all(Vec::is_empty) {
            return vars.iter().position(|v| v.vr == vr && v.ty == ty);
        }
        match self.dense[Self::slot(ty)].get(vr as usize) {
            Some(&i) if i > 0 => Some(usize::from(i) - 1),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each value read as each type: a number is true when it is not zero (also a fraction), a string when
    /// it is not empty; true is 1; a string is no number.
    #[test]
    fn values_convert_as_their_types_say() {
        let bools: Vec<bool> = [
            Value::Real(0.5),
            Value::Real(-2.0),
            Value::Real(0.0),
            Value::Integer(-3),
            Value::Integer(0),
            Value::Boolean(true),
            Value::String("x".into()),
            Value::String(String::new()),
        ]
        .iter()
        .map(Value::as_bool)
        .collect();
        assert_eq!(bools, [true, true, false, true, false, true, true, false]);
        assert_eq!(Value::Real(-2.7).as_integer(), -2);
        assert_eq!(Value::Boolean(true).as_integer(), 1);
        assert_eq!(Value::Integer(-3).as_real(), -3.0);
        assert_eq!(Value::Boolean(false).as_real(), 0.0);
        assert!(Value::String("1".into()).as_real().is_nan());
    }
}

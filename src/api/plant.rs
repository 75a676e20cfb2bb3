//! The plant by the plant FMU's parameter names: one description shared by `backlash simulate`, `backlash
//! crb` and the Python package.
//!
//! The names, their types, ranges and start values are those of BacklashPlant.fmu's model description (the
//! generated variable table), and the values are set on the FMU's own model, which builds the plant: a
//! parameter added to the FMU is known here without a change, and a value means what it means in the FMU.

use crate::fmi::Model;
use crate::fmi::vars::{Causality, Start, Value, VarInfo, VarType};
use crate::fmus::plant::PlantFmu;
use crate::plant::{MAX_ORDER, Plant, PlantOutput, PlantParams};

use super::ApiError;

/// The names that take a list: the coefficients a1..a_na and b0..b_nb (their number sets na and nb).
pub const LIST_NAMES: [&str; 2] = ["a", "b"];

/// One parameter's value: a number, or a list for `a` and `b`.
#[derive(Debug, Clone, PartialEq)]
pub enum SpecValue {
    Number(f64),
    List(Vec<f64>),
}

/// Plant parameters by the plant FMU's names, in the order given (a later value of a name wins); unset ones
/// keep the FMU's start values (paper 000's example).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PlantSpec {
    values: Vec<(String, SpecValue)>,
}

/// The FMU's parameters (not its input and outputs), in the model description's order.
fn parameters() -> impl Iterator<Item = (usize, &'static VarInfo)> {
    PlantFmu::VARIABLES
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Parameter)
}

fn parameter(name: &str) -> Option<(usize, &'static VarInfo)> {
    parameters().find(|(_, v)| v.name == name)
}

impl PlantSpec {
    /// Every name a spec takes: `a` and `b` (lists), then the plant FMU's parameters.
    pub fn names() -> Vec<&'static str> {
        LIST_NAMES
            .into_iter()
            .chain(parameters().map(|(_, v)| v.name))
            .collect()
    }

    /// A parameter of the plant FMU in words, for help texts: its type, range and start value, e.g.
    /// `Integer, min 1, max 64, start 1`; `None` for a name the FMU lacks.
    pub fn describe(name: &str) -> Option<String> {
        let (_, v) = parameter(name)?;
        let mut words = vec![v.ty.name().to_string()];
        words.extend(v.min.map(|m| format!("min {m}")));
        words.extend(v.max.map(|m| format!("max {m}")));
        match v.start {
            Start::Real(x) => words.push(format!("start {x}")),
            Start::Integer(x) => words.push(format!("start {x}")),
            Start::Boolean(x) => words.push(format!("start {x}")),
            Start::None | Start::String(_) => {}
        }
        Some(words.join(", "))
    }

    /// Sets `name` to a number (any FMU parameter but `a` and `b`); an unknown name is refused in words.
    pub fn set(&mut self, name: &str, value: f64) -> Result<&mut Self, ApiError> {
        if LIST_NAMES.contains(&name) {
            return self.set_list(name, &[value]);
        }
        if parameter(name).is_none() {
            return Err(unknown(name));
        }
        self.values
            .push((name.to_string(), SpecValue::Number(value)));
        Ok(self)
    }

    /// Sets `a` (a1..a_na) or `b` (b0..b_nb) to a list of coefficients.
    pub fn set_list(&mut self, name: &str, values: &[f64]) -> Result<&mut Self, ApiError> {
        let (first, most) = match name {
            "a" => (1, MAX_ORDER),
            "b" => (0, MAX_ORDER + 1),
            _ if parameter(name).is_some() => {
                return Err(ApiError::Setting(format!(
                    "{name} takes one number, not a list of {}",
                    values.len()
                )));
            }
            _ => return Err(unknown(name)),
        };
        if values.len() > most || (name == "b" && values.is_empty()) {
            return Err(ApiError::Setting(format!(
                "{name} has {} coefficients; {} to {most} ({name}{first} to {name}{}) are supported",
                values.len(),
                if name == "a" { 0 } else { 1 },
                first + most - 1
            )));
        }
        self.values
            .push((name.to_string(), SpecValue::List(values.to_vec())));
        Ok(self)
    }

    /// Whether `name` was given a value.
    pub fn has(&self, name: &str) -> bool {
        self.values.iter().any(|(n, _)| n == name)
    }

    /// The names given a value, in the order given.
    pub fn given(&self) -> impl Iterator<Item = &str> {
        self.values.iter().map(|(n, _)| n.as_str())
    }

    /// This spec over `base`: where both set a name, this one's value wins.
    pub fn over(mut self, base: &PlantSpec) -> PlantSpec {
        let mut values = base.values.clone();
        values.append(&mut self.values);
        PlantSpec { values }
    }

    /// A spec from a JSON object of names (numbers; lists for `a` and `b`).
    pub fn from_json(text: &str) -> Result<PlantSpec, ApiError> {
        let value: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| ApiError::Setting(format!("not a JSON object of parameters: {e}")))?;
        let serde_json::Value::Object(map) = value else {
            return Err(ApiError::Setting(
                "not a JSON object of parameters ({\"name\": value, ...})".into(),
            ));
        };
        let mut spec = PlantSpec::default();
        for (name, v) in &map {
            let number = |v: &serde_json::Value| {
                v.as_f64()
                    .ok_or_else(|| ApiError::Setting(format!("{name} = {v} is not a number")))
            };
            match v {
                serde_json::Value::Array(items) => {
                    let list = items.iter().map(number).collect::<Result<Vec<_>, _>>()?;
                    spec.set_list(name, &list)?;
                }
                v => {
                    spec.set(name, number(v)?)?;
                }
            }
        }
        Ok(spec)
    }

    /// The FMU's model with these values set and initialised.
    fn model(&self) -> Result<PlantFmu, ApiError> {
        let mut m = <PlantFmu as Model>::new();
        for (i, v) in parameters() {
            let start = match v.start {
                Start::Real(x) => Value::Real(x),
                Start::Integer(x) => Value::Integer(x),
                Start::Boolean(x) => Value::Boolean(x),
                Start::None | Start::String(_) => continue,
            };
            m.set(PlantFmu::var(i), start);
        }
        for (name, value) in &self.values {
            match value {
                SpecValue::Number(x) => set_checked(&mut m, name, *x)?,
                SpecValue::List(c) => {
                    let (count, first, order) = match name.as_str() {
                        "a" => ("na", 1, c.len()),
                        _ => ("nb", 0, c.len().saturating_sub(1)),
                    };
                    set_checked(&mut m, count, order as f64)?;
                    let most = if first == 1 { MAX_ORDER } else { MAX_ORDER + 1 };
                    for j in 0..most {
                        let coefficient = c.get(j).copied().unwrap_or(0.0);
                        set_checked(&mut m, &format!("{name}{}", j + first), coefficient)?;
                    }
                }
            }
        }
        m.exit_initialization().map_err(ApiError::Setting)?;
        Ok(m)
    }

    /// The plant these parameters describe, at sample 0.
    pub fn plant(&self) -> Result<Plant, ApiError> {
        let m = self.model()?;
        Ok(m.plant().expect("initialised above").clone())
    }

    /// The linear block's and the backlash's parameters (with the noise settings).
    pub fn params(&self) -> Result<PlantParams, ApiError> {
        Ok(*self.plant()?.params())
    }
}

/// Sets a parameter as the FMU layer would: a number of the variable's type within the XML's range.
fn set_checked(m: &mut PlantFmu, name: &str, x: f64) -> Result<(), ApiError> {
    let (i, v) = parameter(name).ok_or_else(|| unknown(name))?;
    let bad = |why: String| Err(ApiError::Setting(format!("{name} = {x} {why}")));
    if !x.is_finite() {
        return bad("is not a finite number".into());
    }
    if let Some(lo) = v.min
        && x < lo
    {
        return bad(format!("is below its minimum {lo}"));
    }
    if let Some(hi) = v.max
        && x > hi
    {
        return bad(format!("is above its maximum {hi}"));
    }
    let value = match v.ty {
        VarType::Real => Value::Real(x),
        VarType::Integer | VarType::Boolean if x.fract() != 0.0 || x.abs() > i32::MAX as f64 => {
            return bad(format!("must be a whole number ({})", v.ty.name()));
        }
        VarType::Integer => Value::Integer(x as i32),
        VarType::Boolean => Value::Boolean(x != 0.0),
        VarType::String => return bad("is a String parameter".into()),
    };
    m.set(PlantFmu::var(i), value);
    Ok(())
}

/// An unknown name, in words: the closest known name if one is near, and the list.
fn unknown(name: &str) -> ApiError {
    let names = PlantSpec::names();
    let near = names
        .iter()
        .map(|n| (edit_distance(name, n), *n))
        .filter(|(d, n)| *d <= 2.max(n.len() / 4))
        .min();
    let hint = near.map_or(String::new(), |(_, n)| format!(" (did you mean {n}?)"));
    ApiError::Setting(format!(
        "the plant has no parameter named {name}{hint}; its parameters are the plant FMU's: {}",
        names.join(", ")
    ))
}

/// Levenshtein distance of two short names.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let next = (row[j + 1] + 1)
                .min(row[j] + 1)
                .min(diag + usize::from(ca != cb));
            diag = row[j + 1];
            row[j + 1] = next;
        }
    }
    row[b.len()]
}

/// The plant on an input sequence: output k is the plant's before it reads u(k) (as the FMU at t_k).
pub fn simulate_plant(mut plant: Plant, u: &[f64]) -> Vec<PlantOutput> {
    u.iter()
        .map(|&uk| {
            let o = plant.output();
            plant.advance(uk);
            o
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_fmu_start_values_and_names_come_from_the_fmu() {
        assert_eq!(PlantSpec::default().params().unwrap(), PlantParams::PAPER);
        let names = PlantSpec::names();
        for n in [
            "a",
            "b",
            "Ts",
            "na",
            "c1",
            "c1_rate",
            "noise_phi",
            "b4_fall",
        ] {
            assert!(names.contains(&n), "{n}");
        }
        assert!(!names.contains(&"u") && !names.contains(&"y"));
        assert_eq!(
            PlantSpec::describe("delay").as_deref(),
            Some("Integer, min 1, max 64, start 1")
        );
        assert_eq!(PlantSpec::describe("u"), None);
    }

    #[test]
    fn lists_set_the_orders_and_unknown_names_are_refused_in_words() {
        let mut s = PlantSpec::default();
        s.set_list("a", &[0.5])
            .unwrap()
            .set_list("b", &[0.2, 0.3])
            .unwrap();
        s.set("m2", 2.0).unwrap();
        let p = s.params().unwrap();
        assert_eq!((p.arx.na, p.arx.nb), (1, 1));
        assert_eq!((p.arx.a[0], p.arx.a[1], p.arx.b[1]), (0.5, 0.0, 0.3));
        assert_eq!(p.backlash.m2, 2.0);
        let e = PlantSpec::default()
            .set("c1_rat", 1.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("the plant has no parameter named c1_rat (did you mean c1_rate?)"),
            "{e}"
        );
        let e = PlantSpec::default()
            .set_list("a", &[0.1; 5])
            .unwrap_err()
            .to_string();
        assert!(e.contains("a has 5 coefficients; 0 to 4 (a1 to a4)"), "{e}");
        let mut s = PlantSpec::default();
        s.set("delay", 1.5).unwrap();
        assert_eq!(
            s.plant().unwrap_err().to_string(),
            "delay = 1.5 must be a whole number (Integer)"
        );
        let mut s = PlantSpec::default();
        s.set("c1", -1.0).unwrap();
        assert_eq!(
            s.plant().unwrap_err().to_string(),
            "c1 = -1 is below its minimum 0"
        );
    }

    #[test]
    fn a_test_bench_parameter_acts_as_in_the_fmu() {
        let u: Vec<f64> = (0..200).map(|k| (k as f64 * 0.1).sin() * 3.0).collect();
        let plain = simulate_plant(PlantSpec::default().plant().unwrap(), &u);
        assert_eq!(plain, Plant::simulate(PlantParams::PAPER, &u).unwrap());
        let mut s = PlantSpec::default();
        s.set("quant_step", 0.5).unwrap();
        let q = simulate_plant(s.plant().unwrap(), &u);
        assert!(q.iter().all(|o| (o.y / 0.5).fract() == 0.0));
        assert_ne!(q, plain);
        let json = PlantSpec::from_json(r#"{"a": [0.5], "quant_step": 0.5}"#).unwrap();
        assert!(json.has("quant_step") && json.has("a"));
        let e = PlantSpec::from_json(r#"{"c3": 1}"#)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("the plant has no parameter named c3"), "{e}");
    }
}

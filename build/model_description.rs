//! Reads modelDescription/*.xml (quick-xml + serde), checks each description, and writes the Rust tables.
//!
//! The XML is the one source: the variable table, the GUID and the model identifier the FMUs use at run time
//! are generated from it. Every problem found here fails the build with the file, the variable and the reason.

use serde::Deserialize;
use std::collections::HashSet;
use std::fmt::Write as _;

#[derive(Debug, Deserialize)]
pub struct ModelDescription {
    #[serde(rename = "@fmiVersion")]
    pub fmi_version: String,
    #[serde(rename = "@modelName")]
    pub model_name: String,
    #[serde(rename = "@guid")]
    pub guid: String,
    #[serde(rename = "CoSimulation")]
    pub co_simulation: CoSimulation,
    #[serde(rename = "LogCategories")]
    pub log_categories: LogCategories,
    #[serde(rename = "ModelVariables")]
    pub model_variables: ModelVariables,
    #[serde(rename = "ModelStructure")]
    pub model_structure: ModelStructure,
}

#[derive(Debug, Deserialize)]
pub struct CoSimulation {
    #[serde(rename = "@modelIdentifier")]
    pub model_identifier: String,
    #[serde(rename = "@canGetAndSetFMUstate", default)]
    pub can_get_and_set_fmu_state: Option<String>,
    #[serde(rename = "@canSerializeFMUstate", default)]
    pub can_serialize_fmu_state: Option<String>,
}

#[derive(Debug, Deserialize)]
pub struct LogCategories {
    #[serde(rename = "Category", default)]
    pub categories: Vec<Category>,
}

#[derive(Debug, Deserialize)]
pub struct Category {
    #[serde(rename = "@name")]
    pub name: String,
}

#[derive(Debug, Deserialize)]
pub struct ModelVariables {
    #[serde(rename = "ScalarVariable", default)]
    pub variables: Vec<ScalarVariable>,
}

#[derive(Debug, Deserialize)]
pub struct ScalarVariable {
    #[serde(rename = "@name")]
    pub name: String,
    #[serde(rename = "@valueReference")]
    pub value_reference: u32,
    #[serde(rename = "@causality", default)]
    pub causality: Option<String>,
    #[serde(rename = "@variability", default)]
    pub variability: Option<String>,
    #[serde(rename = "@initial", default)]
    pub initial: Option<String>,
    #[serde(rename = "@description", default)]
    pub description: Option<String>,
    #[serde(rename = "Real", default)]
    pub real: Option<TypeAttrs>,
    #[serde(rename = "Integer", default)]
    pub integer: Option<TypeAttrs>,
    #[serde(rename = "Boolean", default)]
    pub boolean: Option<TypeAttrs>,
    #[serde(rename = "String", default)]
    pub string: Option<TypeAttrs>,
}

#[derive(Debug, Deserialize)]
pub struct TypeAttrs {
    #[serde(rename = "@start", default)]
    pub start: Option<String>,
    #[serde(rename = "@min", default)]
    pub min: Option<String>,
    #[serde(rename = "@max", default)]
    pub max: Option<String>,
    #[serde(rename = "@unit", default)]
    pub unit: Option<String>,
}

#[derive(Debug, Deserialize)]
pub struct ModelStructure {
    #[serde(rename = "Outputs", default)]
    pub outputs: Option<UnknownList>,
    #[serde(rename = "InitialUnknowns", default)]
    pub initial_unknowns: Option<UnknownList>,
}

#[derive(Debug, Deserialize)]
pub struct UnknownList {
    #[serde(rename = "Unknown", default)]
    pub unknowns: Vec<Unknown>,
}

#[derive(Debug, Deserialize)]
pub struct Unknown {
    #[serde(rename = "@index")]
    pub index: usize,
}

/// Parse and check one description; `stem` is the file name without extension.
pub fn load(stem: &str, text: &str) -> Result<ModelDescription, String> {
    check_attribute_values(text)?;
    let md: ModelDescription =
        quick_xml::de::from_str(text).map_err(|e| format!("cannot parse: {e}"))?;
    check(stem, &md)?;
    Ok(md)
}

/// XML forbids a raw `<` in an attribute value; quick-xml's deserializer lets it through, strict parsers
/// (lxml in FMPy) reject the whole file. Checked here so that the build fails instead of the importer.
fn check_attribute_values(text: &str) -> Result<(), String> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(text);
    loop {
        let pos = reader.buffer_position();
        match reader.read_event() {
            Ok(Event::Start(e) | Event::Empty(e)) => {
                for a in e.attributes() {
                    let a = a.map_err(|err| format!("bad attribute near byte {pos}: {err}"))?;
                    if a.value.contains('<') {
                        let line = text[..pos as usize].matches('\n').count() + 1;
                        return Err(format!(
                            "line {line}: attribute '{}' contains a raw '<' (write &lt;)",
                            a.key.as_ref() as &str
                        ));
                    }
                }
            }
            Ok(Event::Eof) => return Ok(()),
            Ok(_) => {}
            Err(err) => return Err(format!("cannot parse near byte {pos}: {err}")),
        }
    }
}

fn type_of(v: &ScalarVariable) -> Result<(&'static str, &TypeAttrs), String> {
    let kinds = [
        ("Real", v.real.as_ref()),
        ("Integer", v.integer.as_ref()),
        ("Boolean", v.boolean.as_ref()),
        ("String", v.string.as_ref()),
    ];
    let present: Vec<_> = kinds.iter().filter(|(_, a)| a.is_some()).collect();
    match present.as_slice() {
        [(k, Some(a))] => Ok((k, a)),
        _ => Err(format!(
            "variable '{}' must have exactly one of Real, Integer, Boolean, String",
            v.name
        )),
    }
}

/// The description's checks: its header, every variable, and the model structure.
fn check(stem: &str, md: &ModelDescription) -> Result<(), String> {
    check_header(stem, md)?;
    let mut names = HashSet::new();
    let mut vrs = HashSet::new();
    for v in &md.model_variables.variables {
        let (ty, attrs) = type_of(v)?;
        let at = |what: &str| format!("variable '{}': {what}", v.name);
        if !names.insert(v.name.as_str()) {
            return Err(at("name appears twice"));
        }
        if !vrs.insert((ty, v.value_reference)) {
            return Err(at(&format!(
                "valueReference {} is used twice for {ty}",
                v.value_reference
            )));
        }
        check_variable(v, ty, attrs).map_err(|what| at(&what))?;
    }
    check_structure(md)
}

/// The version, the names, the GUID, the FMU-state flags and the log categories the FMI layer needs.
fn check_header(stem: &str, md: &ModelDescription) -> Result<(), String> {
    if md.fmi_version != "2.0" {
        return Err(format!(
            "fmiVersion is '{}', expected '2.0'",
            md.fmi_version
        ));
    }
    if md.co_simulation.model_identifier != stem || md.model_name != stem {
        return Err(format!(
            "modelName '{}' and modelIdentifier '{}' must both equal the file name '{stem}'",
            md.model_name, md.co_simulation.model_identifier
        ));
    }
    let guid = md.guid.trim_matches(|c| c == '{' || c == '}');
    if guid.len() != 36 || !guid.chars().all(|c| c.is_ascii_hexdigit() || c == '-') {
        return Err(format!("guid '{}' is not a UUID", md.guid));
    }
    for (flag, v) in [
        (
            "canGetAndSetFMUstate",
            &md.co_simulation.can_get_and_set_fmu_state,
        ),
        (
            "canSerializeFMUstate",
            &md.co_simulation.can_serialize_fmu_state,
        ),
    ] {
        if v.as_deref() != Some("true") {
            return Err(format!(
                "CoSimulation/@{flag} must be \"true\": the FMI layer implements FMU state"
            ));
        }
    }
    let cats: Vec<&str> = md
        .log_categories
        .categories
        .iter()
        .map(|c| c.name.as_str())
        .collect();
    for needed in ["logStatusError", "logStatusWarning", "logCalls", "logAll"] {
        if !cats.contains(&needed) {
            return Err(format!(
                "LogCategories must declare '{needed}' (the FMI layer logs under it)"
            ));
        }
    }
    Ok(())
}

/// One variable on its own: a flat name, a description, a supported causality and variability with the
/// `initial` and start they need, a unit for a Real, numbers within their bounds. The error says what is wrong
/// (the caller names the variable).
fn check_variable(v: &ScalarVariable, ty: &str, attrs: &TypeAttrs) -> Result<(), String> {
    let mut chars = v.name.chars();
    let flat = chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !flat {
        return Err("name must be a flat identifier".into());
    }
    if v.description.as_deref().is_none_or(str::is_empty) {
        return Err("needs a description".into());
    }
    let causality = v.causality.as_deref().unwrap_or("local");
    let variability = v.variability.as_deref().unwrap_or("continuous");
    match (causality, variability) {
        ("parameter", "fixed" | "tunable") => {
            if v.initial.as_deref() != Some("exact") || attrs.start.is_none() {
                return Err("a parameter needs initial=\"exact\" and a start value".into());
            }
        }
        ("input", "discrete" | "continuous") => {
            if attrs.start.is_none() {
                return Err("an input needs a start value".into());
            }
        }
        ("output", "discrete" | "continuous") => {
            if v.initial.as_deref() != Some("calculated") || attrs.start.is_some() {
                return Err(
                    "outputs are computed by the model: initial=\"calculated\" and no start".into(),
                );
            }
        }
        _ => {
            return Err(format!(
                "causality '{causality}' with variability '{variability}' is not supported"
            ));
        }
    }
    if ty == "Real" && attrs.unit.is_none() {
        return Err("a Real needs a unit".into());
    }
    if ty == "Real" || ty == "Integer" {
        check_bounds(attrs)?;
    }
    if ty == "Boolean"
        && let Some(s) = &attrs.start
        && s != "true"
        && s != "false"
    {
        return Err("a Boolean start must be true or false".into());
    }
    Ok(())
}

/// A number's start, min and max are numbers, min <= max, and the start within them.
fn check_bounds(attrs: &TypeAttrs) -> Result<(), String> {
    let num = |s: &Option<String>, what: &str| -> Result<Option<f64>, String> {
        s.as_deref()
            .map(|t| {
                t.parse::<f64>()
                    .map_err(|_| format!("{what} '{t}' is not a number"))
            })
            .transpose()
    };
    let (start, min, max) = (
        num(&attrs.start, "start")?,
        num(&attrs.min, "min")?,
        num(&attrs.max, "max")?,
    );
    if let (Some(lo), Some(hi)) = (min, max)
        && lo > hi
    {
        return Err("min > max".into());
    }
    if let Some(s) = start
        && (min.is_some_and(|lo| s < lo) || max.is_some_and(|hi| s > hi))
    {
        return Err("start is outside [min, max]".into());
    }
    Ok(())
}

/// ModelStructure: Outputs lists exactly the outputs in order; InitialUnknowns lists exactly the calculated
/// outputs (there are no calculated parameters or states in these FMUs).
fn check_structure(md: &ModelDescription) -> Result<(), String> {
    let outputs: Vec<usize> = md
        .model_variables
        .variables
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality.as_deref() == Some("output"))
        .map(|(i, _)| i + 1)
        .collect();
    let listed = |l: &Option<UnknownList>| -> Vec<usize> {
        l.as_ref()
            .map(|l| l.unknowns.iter().map(|u| u.index).collect())
            .unwrap_or_default()
    };
    let structure_outputs = listed(&md.model_structure.outputs);
    if structure_outputs != outputs {
        return Err(format!(
            "ModelStructure/Outputs lists indices {structure_outputs:?}; the outputs are at {outputs:?} \
             (1-based ScalarVariable order)"
        ));
    }
    let initial = listed(&md.model_structure.initial_unknowns);
    if initial != outputs {
        return Err(format!(
            "ModelStructure/InitialUnknowns lists {initial:?}; the calculated outputs are at {outputs:?}"
        ));
    }
    Ok(())
}

fn camel(name: &str) -> String {
    let mut out = String::new();
    let mut up = true;
    for c in name.chars() {
        if c == '_' {
            up = true;
        } else if up {
            out.extend(c.to_uppercase());
            up = false;
        } else {
            out.push(c);
        }
    }
    out
}

fn lit(v: &str) -> String {
    let x: f64 = v.parse().expect("checked");
    if x.is_finite() {
        format!("{x:?}")
    } else {
        panic!("non-finite literal {v}")
    }
}

/// Rust source for one description: a module named after the model with its identity, the variable table
/// and an enum with one variant per variable (adapters match on it exhaustively).
pub fn generate(module: &str, md: &ModelDescription) -> String {
    let mut s = String::new();
    let vars = &md.model_variables.variables;
    writeln!(
        s,
        "/// Generated from modelDescription/{}.xml.",
        md.model_name
    )
    .unwrap();
    writeln!(s, "pub mod {module} {{").unwrap();
    writeln!(s, "    use crate::fmi::vars::*;").unwrap();
    writeln!(
        s,
        "    pub const MODEL_IDENTIFIER: &str = {:?};",
        md.co_simulation.model_identifier
    )
    .unwrap();
    writeln!(s, "    pub const GUID: &str = {:?};", md.guid).unwrap();
    let cats: Vec<String> = md
        .log_categories
        .categories
        .iter()
        .map(|c| format!("{:?}", c.name))
        .collect();
    writeln!(
        s,
        "    pub const LOG_CATEGORIES: &[&str] = &[{}];",
        cats.join(", ")
    )
    .unwrap();
    writeln!(
        s,
        "    /// One variant per ScalarVariable, in XML order.\n    #[derive(Debug, Clone, Copy, PartialEq, Eq)]\n    pub enum Var {{"
    )
    .unwrap();
    for v in vars {
        writeln!(s, "        {},", camel(&v.name)).unwrap();
    }
    writeln!(s, "    }}").unwrap();
    writeln!(s, "    impl Var {{").unwrap();
    writeln!(
        s,
        "        /// All variables, index-aligned with [`VARIABLES`]."
    )
    .unwrap();
    writeln!(s, "        pub const ALL: [Var; {}] = [", vars.len()).unwrap();
    for v in vars {
        writeln!(s, "            Var::{},", camel(&v.name)).unwrap();
    }
    writeln!(s, "        ];\n    }}").unwrap();
    writeln!(s, "    pub const VARIABLES: [VarInfo; {}] = [", vars.len()).unwrap();
    for v in vars {
        writeln!(s, "        {},", var_info(v)).unwrap();
    }
    writeln!(s, "    ];\n}}").unwrap();
    s
}

/// The `VarInfo` literal of one (checked) variable.
fn var_info(v: &ScalarVariable) -> String {
    let (ty, a) = type_of(v).expect("checked");
    let causality = match v.causality.as_deref().unwrap_or("local") {
        "parameter" => "Parameter",
        "input" => "Input",
        "output" => "Output",
        other => panic!("unsupported causality {other}"),
    };
    let variability = match v.variability.as_deref().unwrap_or("continuous") {
        "fixed" => "Fixed",
        "tunable" => "Tunable",
        "discrete" => "Discrete",
        "continuous" => "Continuous",
        other => panic!("unsupported variability {other}"),
    };
    let start = match (ty, &a.start) {
        (_, None) => "Start::None".to_string(),
        ("Real", Some(x)) => format!("Start::Real({})", lit(x)),
        ("Integer", Some(x)) => format!("Start::Integer({})", x.parse::<i32>().expect("int")),
        ("Boolean", Some(x)) => format!("Start::Boolean({})", x == "true"),
        (_, Some(x)) => format!("Start::String({x:?})"),
    };
    let opt = |o: &Option<String>| match o {
        Some(x) => format!("Some({})", lit(x)),
        None => "None".into(),
    };
    format!(
        "VarInfo {{ name: {:?}, vr: {}, ty: VarType::{ty}, causality: Causality::{causality}, \
         variability: Variability::{variability}, start: {start}, min: {}, max: {} }}",
        v.name,
        v.value_reference,
        opt(&a.min),
        opt(&a.max)
    )
}

//! Writes the FMI 3.0 model description of an FMU from its FMI 2.0 one (modelDescription/<Model>.xml, the
//! one hand-kept source): the same variables, attributes, units, log categories and default experiment,
//! in FMI 3.0's form.
//!
//! The FMI 2.0 text is read event by event (quick-xml) and copied, except: the root gets fmiVersion 3.0 and
//! instantiationToken (the GUID); CoSimulation gets FMI 3.0's capability flags; each ScalarVariable with
//! its type element becomes one typed element (Real -> Float64, Integer -> Int32, Boolean -> Boolean); the
//! independent variable `time` ([`TIME_VR`]) comes first; ModelStructure refers to value references
//! instead of indices. FMI 3.0 wants value references unique over all variables: checked here.

use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};
use std::collections::HashMap;
use std::fmt::Write as _;

/// Value reference of the independent variable `time` in every FMI 3.0 description (the layer reads it
/// from the generated `fmi3_time.rs`).
pub const TIME_VR: u32 = 0;

/// Rust source that gives the FMI 3.0 layer [`TIME_VR`].
pub fn time_vr_source() -> String {
    format!(
        "/// Value reference of the independent variable `time` in the FMI 3.0 descriptions (build.rs).\n\
         pub const TIME_VR: u32 = {TIME_VR};\n"
    )
}

/// The element's attributes as (name, raw value) pairs: values stay escaped as in the source.
fn attrs(e: &BytesStart) -> Result<Vec<(String, String)>, String> {
    e.attributes()
        .map(|a| {
            let a = a.map_err(|err| format!("bad attribute: {err}"))?;
            let key = a.key.as_ref().to_string();
            Ok((key, a.value.into_owned()))
        })
        .collect()
}

fn get<'a>(attrs: &'a [(String, String)], key: &str) -> Option<&'a str> {
    attrs
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

fn tag(name: &str, attrs: &[(String, String)], empty: bool) -> String {
    let mut s = format!("<{name}");
    for (k, v) in attrs {
        write!(s, " {k}=\"{v}\"").unwrap();
    }
    s.push_str(if empty { "/>" } else { ">" });
    s
}

/// FMI 2.0 descriptions name their calls and statuses fmi2*; the FMI 3.0 ones say fmi3*.
fn to_fmi3_words(text: &str) -> String {
    text.replace("fmi2", "fmi3")
}

fn name_of(e: &BytesStart) -> String {
    e.name().as_ref().to_string()
}

/// The root element's attributes for FMI 3.0.
fn root(a: Vec<(String, String)>) -> Vec<(String, String)> {
    a.into_iter()
        .filter(|(k, _)| k != "numberOfEventIndicators")
        .map(|(k, v)| match k.as_str() {
            "fmiVersion" => (k, "3.0".to_string()),
            "guid" => ("instantiationToken".to_string(), v),
            "description" => (k, to_fmi3_words(&v)),
            _ => (k, v),
        })
        .collect()
}

/// The CoSimulation element for FMI 3.0: identity and step-size flags from the FMI 2.0 element, FMU state
/// as there, and what the FMI 3.0 layer provides (no event mode, clocks, early return or derivatives).
fn co_simulation(a: &[(String, String)]) -> Result<Vec<(String, String)>, String> {
    let copy = |k: &str| {
        get(a, k)
            .map(str::to_string)
            .ok_or_else(|| format!("CoSimulation/@{k} is missing"))
    };
    let fixed = |k: &str, v: &str| (k.to_string(), v.to_string());
    Ok(vec![
        ("modelIdentifier".into(), copy("modelIdentifier")?),
        (
            "canHandleVariableCommunicationStepSize".into(),
            copy("canHandleVariableCommunicationStepSize")?,
        ),
        ("canGetAndSetFMUState".into(), copy("canGetAndSetFMUstate")?),
        ("canSerializeFMUState".into(), copy("canSerializeFMUstate")?),
        (
            "maxOutputDerivativeOrder".into(),
            copy("maxOutputDerivativeOrder")?,
        ),
        fixed("providesDirectionalDerivatives", "false"),
        fixed("providesAdjointDerivatives", "false"),
        fixed("providesPerElementDependencies", "false"),
        fixed("providesIntermediateUpdate", "false"),
        fixed("mightReturnEarlyFromDoStep", "false"),
        fixed("canReturnEarlyAfterIntermediateUpdate", "false"),
        fixed("hasEventMode", "false"),
        fixed("providesEvaluateDiscreteStates", "false"),
    ])
}

/// One FMI 2.0 ScalarVariable with its type element, as one FMI 3.0 typed element.
fn variable(sv: &[(String, String)], ty: &str, ta: &[(String, String)]) -> Result<String, String> {
    let name = get(sv, "name").unwrap_or("?");
    let element = match ty {
        "Real" => "Float64",
        "Integer" => "Int32",
        "Boolean" => "Boolean",
        other => {
            return Err(format!(
                "variable '{name}': type {other} has no FMI 3.0 translation here (Real, Integer, Boolean)"
            ));
        }
    };
    let mut all: Vec<(String, String)> = sv
        .iter()
        .map(|(k, v)| {
            let v = if k == "description" {
                to_fmi3_words(v)
            } else {
                v.clone()
            };
            (k.clone(), v)
        })
        .collect();
    all.extend(ta.iter().cloned());
    Ok(tag(element, &all, true))
}

/// The FMI 3.0 description of the FMI 2.0 description `text` of `stem`.
pub fn model_description(stem: &str, text: &str) -> Result<String, String> {
    let mut reader = Reader::from_str(text);
    let mut out = String::new();
    // The ScalarVariable being read: its attributes, then its type element's.
    let mut sv: Option<Vec<(String, String)>> = None;
    let mut ty: Option<(String, Vec<(String, String)>)> = None;
    // Value reference of each variable, in order (ModelStructure's indices are 1-based into it).
    let mut vrs: Vec<u32> = Vec::new();
    let mut seen: HashMap<u32, String> = HashMap::new();
    let mut in_structure = false;
    let mut structure: Vec<String> = Vec::new();
    let mut list = "";
    loop {
        let start = reader.buffer_position() as usize;
        let event = reader
            .read_event()
            .map_err(|e| format!("cannot parse near byte {start}: {e}"))?;
        let raw = &text[start..reader.buffer_position() as usize];
        match event {
            Event::Eof => break,
            Event::Decl(_) => {
                out.push_str(raw);
                out.push_str(&generated_note(stem));
            }
            Event::Comment(_) => {}
            Event::Start(e) | Event::Empty(e) if sv.is_some() => {
                ty = Some((name_of(&e), attrs(&e)?));
            }
            Event::Start(e) if name_of(&e) == "ScalarVariable" => sv = Some(attrs(&e)?),
            Event::End(e) if sv.is_some() => {
                if e.name().as_ref() == "ScalarVariable" {
                    let a = sv.take().expect("inside a ScalarVariable");
                    out.push_str(&close_variable(&a, ty.take(), &mut seen, &mut vrs)?);
                }
            }
            Event::Text(_) if sv.is_some() => {}
            Event::Start(e) if name_of(&e) == "fmiModelDescription" => {
                out.push_str(&tag("fmiModelDescription", &root(attrs(&e)?), false));
            }
            Event::Start(e) | Event::Empty(e) if name_of(&e) == "CoSimulation" => {
                out.push_str(&tag("CoSimulation", &co_simulation(&attrs(&e)?)?, true));
            }
            Event::Start(e) if name_of(&e) == "ModelVariables" => {
                out.push_str(raw);
                write!(
                    out,
                    "\n    <Float64 name=\"time\" valueReference=\"{TIME_VR}\" causality=\"independent\" \
                     variability=\"continuous\" description=\"Simulation time\"/>"
                )
                .unwrap();
            }
            Event::Start(e) if name_of(&e) == "ModelStructure" => in_structure = true,
            Event::Start(e) | Event::Empty(e) if in_structure => match name_of(&e).as_str() {
                "Outputs" => list = "Output",
                "InitialUnknowns" => list = "InitialUnknown",
                "Unknown" if !list.is_empty() => {
                    structure.push(unknown(list, &attrs(&e)?, &vrs)?);
                }
                other => {
                    return Err(format!(
                        "ModelStructure/{other} has no FMI 3.0 translation here (Outputs, InitialUnknowns)"
                    ));
                }
            },
            Event::End(e) if in_structure => {
                if e.name().as_ref() == "ModelStructure" {
                    in_structure = false;
                    out.push_str(&structure_element(&structure));
                } else {
                    list = "";
                }
            }
            Event::Text(_) if in_structure => {}
            _ => out.push_str(&to_fmi3_words(raw)),
        }
    }
    Ok(out)
}

/// The comment after the XML declaration that says where the description comes from.
fn generated_note(stem: &str) -> String {
    format!(
        "\n<!-- Generated by build.rs from modelDescription/{stem}.xml (the FMI 2.0 description, the one \
         source of the variables): edit that file, not this one. -->"
    )
}

/// The FMI 3.0 ModelStructure element holding the translated `entries`.
fn structure_element(entries: &[String]) -> String {
    let mut out = String::from("<ModelStructure>");
    for s in entries {
        write!(out, "\n    {s}").unwrap();
    }
    out.push_str("\n  </ModelStructure>");
    out
}

/// A ScalarVariable read to its end (attributes `a`, its type element `ty`) as an FMI 3.0 variable element;
/// its value reference must be unique over all types and not the independent variable's (`seen`, `vrs`
/// collect them).
fn close_variable(
    a: &[(String, String)],
    ty: Option<(String, Vec<(String, String)>)>,
    seen: &mut HashMap<u32, String>,
    vrs: &mut Vec<u32>,
) -> Result<String, String> {
    let (t, ta) = ty.ok_or_else(|| "a ScalarVariable without a type element".to_string())?;
    let name = get(a, "name").unwrap_or("?").to_string();
    let vr: u32 = get(a, "valueReference")
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| format!("variable '{name}': bad valueReference"))?;
    if vr == TIME_VR {
        return Err(format!(
            "variable '{name}': valueReference {TIME_VR} is the FMI 3.0 description's \
             independent variable 'time'"
        ));
    }
    if let Some(other) = seen.insert(vr, name.clone()) {
        return Err(format!(
            "variables '{other}' and '{name}' share valueReference {vr}: FMI 3.0 wants value \
             references unique over all types"
        ));
    }
    vrs.push(vr);
    variable(a, &t, &ta)
}

/// An FMI 2.0 Unknown (1-based variable indices) as an FMI 3.0 Output or InitialUnknown (value references).
fn unknown(element: &str, a: &[(String, String)], vrs: &[u32]) -> Result<String, String> {
    let vr_of = |index: &str| -> Result<String, String> {
        index
            .parse::<usize>()
            .ok()
            .and_then(|i| i.checked_sub(1))
            .and_then(|i| vrs.get(i))
            .map(u32::to_string)
            .ok_or_else(|| format!("ModelStructure: index '{index}' names no variable"))
    };
    let mut out = vec![(
        "valueReference".to_string(),
        vr_of(get(a, "index").unwrap_or(""))?,
    )];
    // An empty list (FMI 2.0's way to say "no direct feedthrough") is left out: in FMI 3.0 an absent attribute
    // means "depends on all knowns", harmless for co-simulation, and an empty one crashes importers
    // (OMSimulator 3.0's fmi4c) before they load the binary.
    let deps = get(a, "dependencies").filter(|d| !d.trim().is_empty());
    if let Some(deps) = deps {
        let deps = deps
            .split_whitespace()
            .map(vr_of)
            .collect::<Result<Vec<_>, _>>()?;
        out.push(("dependencies".into(), deps.join(" ")));
        if let Some(kinds) = get(a, "dependenciesKind") {
            out.push(("dependenciesKind".into(), kinds.to_string()));
        }
    }
    Ok(tag(element, &out, true))
}

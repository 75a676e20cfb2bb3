//! What an FMI tool shows of an FMU besides its variables: `documentation/index.html` and the icon, both made
//! from the description the FMU carries (FMI 2.0 or the FMI 3.0 text build/fmi3.rs writes), so that a
//! variable added to modelDescription/ is documented and drawn by construction (packaging/build.rs).
//!
//! The page lists every variable with its causality, variability, type, unit, start, range and description;
//! the timing (default experiment, step sizes, which outputs an input reaches within the same step); and a
//! minimal FMPy example. The icon is the backlash characteristic with one port per input and per output
//! (build/icon.rs).

use quick_xml::Reader;
use quick_xml::events::{BytesStart, Event};
use std::fmt::Write as _;

/// One variable: its element (`Real`, `Float64`, ...) and the attributes of the variable and its type.
pub struct Variable {
    pub ty: String,
    pub attrs: Vec<(String, String)>,
}

impl Variable {
    pub fn get(&self, key: &str) -> Option<&str> {
        get(&self.attrs, key)
    }

    fn name(&self) -> &str {
        self.get("name").unwrap_or("?")
    }

    fn causality(&self) -> &str {
        self.get("causality").unwrap_or("local")
    }
}

/// An element's attributes: (name, value) in order, values unescaped.
pub type Attributes = Vec<(String, String)>;

/// What the page and the icon are made from.
pub struct Description {
    pub root: Vec<(String, String)>,
    pub co_simulation: Vec<(String, String)>,
    pub default_experiment: Vec<(String, String)>,
    pub variables: Vec<Variable>,
    /// ModelStructure's outputs: (index or value reference, dependencies) as written.
    pub outputs: Vec<(Attributes, Option<String>)>,
}

impl Description {
    pub fn fmi3(&self) -> bool {
        get(&self.root, "fmiVersion").is_some_and(|v| v.starts_with('3'))
    }

    pub fn name(&self) -> &str {
        get(&self.root, "modelName").unwrap_or("?")
    }

    /// The variables of one causality, in the description's order.
    pub fn with_causality<'a>(&'a self, causality: &'a str) -> impl Iterator<Item = &'a Variable> {
        self.variables
            .iter()
            .filter(move |v| v.causality() == causality)
    }

    /// The variable an output or dependency entry names: a 1-based index (FMI 2.0) or a value reference
    /// (FMI 3.0, unique over all variables).
    fn lookup(&self, key: &str) -> Option<&Variable> {
        let n: usize = key.parse().ok()?;
        if self.fmi3() {
            self.variables
                .iter()
                .find(|v| v.get("valueReference") == Some(key))
        } else {
            self.variables.get(n.checked_sub(1)?)
        }
    }
}

fn get<'a>(attrs: &'a [(String, String)], key: &str) -> Option<&'a str> {
    attrs
        .iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v.as_str())
}

/// The element's attributes, unescaped.
fn attrs(e: &BytesStart) -> Result<Vec<(String, String)>, String> {
    e.attributes()
        .map(|a| {
            let a = a.map_err(|err| format!("bad attribute: {err}"))?;
            let raw = a.value.into_owned();
            let value = quick_xml::escape::unescape(&raw)
                .map_err(|err| format!("bad attribute value '{raw}': {err}"))?
                .into_owned();
            Ok((a.key.as_ref().to_string(), value))
        })
        .collect()
}

/// Where the reader is: the element names from the root down.
fn inside(path: &[String], parent: &str) -> bool {
    path.last().is_some_and(|p| p == parent)
}

/// Reads an FMI 2.0 or 3.0 model description.
pub fn read(text: &str) -> Result<Description, String> {
    let mut d = Description {
        root: Vec::new(),
        co_simulation: Vec::new(),
        default_experiment: Vec::new(),
        variables: Vec::new(),
        outputs: Vec::new(),
    };
    let mut reader = Reader::from_str(text);
    let mut path: Vec<String> = Vec::new();
    loop {
        let pos = reader.buffer_position();
        let event = reader
            .read_event()
            .map_err(|e| format!("cannot parse near byte {pos}: {e}"))?;
        match event {
            Event::Eof => return Ok(d),
            Event::Start(e) => {
                element(&mut d, &path, &e)?;
                path.push(e.name().as_ref().to_string());
            }
            Event::Empty(e) => element(&mut d, &path, &e)?,
            Event::End(_) => {
                path.pop();
            }
            _ => {}
        }
    }
}

/// One element of the description, at `path`.
fn element(d: &mut Description, path: &[String], e: &BytesStart) -> Result<(), String> {
    let name = e.name().as_ref().to_string();
    let a = attrs(e)?;
    match name.as_str() {
        "fmiModelDescription" => d.root = a,
        "CoSimulation" => d.co_simulation = a,
        "DefaultExperiment" => d.default_experiment = a,
        // FMI 2.0: the type element inside a ScalarVariable adds its attributes (start, unit, ...).
        _ if inside(path, "ScalarVariable") => {
            if let Some(v) = d.variables.last_mut() {
                v.ty = name;
                v.attrs.extend(a);
            }
        }
        // FMI 2.0: a ScalarVariable (its type comes next); FMI 3.0: the typed element itself.
        _ if inside(path, "ModelVariables") => d.variables.push(Variable { ty: name, attrs: a }),
        "Unknown" if inside(path, "Outputs") => {
            let deps = get(&a, "dependencies").map(str::to_string);
            d.outputs.push((a, deps));
        }
        "Output" if inside(path, "ModelStructure") => {
            let deps = get(&a, "dependencies").map(str::to_string);
            d.outputs.push((a, deps));
        }
        _ => {}
    }
    Ok(())
}

/// Text for HTML.
fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// `documentation/index.html` of the FMU with description `xml`.
pub fn index_html(xml: &str) -> Result<String, String> {
    let d = read(xml)?;
    let name = esc(d.name());
    let version = if d.fmi3() { "3.0" } else { "2.0" };
    let mut s = String::new();
    writeln!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{name}</title>\n\
         <style>body{{font-family:sans-serif;max-width:70em;margin:1em auto;padding:0 1em}}\
         table{{border-collapse:collapse}}td,th{{border:1px solid #bbb;padding:.2em .4em;vertical-align:top}}\
         th{{background:#eef}}code,pre{{background:#f6f6f6}}pre{{padding:.5em}}</style>\n</head>\n<body>"
    )
    .unwrap();
    writeln!(
        s,
        "<h1>{name}</h1>\n<p>FMI {version} co-simulation FMU (model identifier <code>{}</code>), \
         generated by {}.</p>\n<p>{}</p>",
        esc(get(&d.co_simulation, "modelIdentifier").unwrap_or("?")),
        esc(get(&d.root, "generationTool").unwrap_or("its build")),
        esc(get(&d.root, "description").unwrap_or("")),
    )
    .unwrap();
    s.push_str(&timing(&d));
    s.push_str(&variables(&d));
    s.push_str(&example(&d));
    s.push_str("</body>\n</html>\n");
    Ok(s)
}

/// The timing: the default experiment, the step sizes, the sample period, which outputs react to an input
/// within the step.
fn timing(d: &Description) -> String {
    let mut s = String::from("<h2>Timing</h2>\n<ul>\n");
    if !d.default_experiment.is_empty() {
        let parts: Vec<String> = d
            .default_experiment
            .iter()
            .map(|(k, v)| format!("{} = {}", esc(k), esc(v)))
            .collect();
        writeln!(s, "<li>Default experiment: {} (s).</li>", parts.join(", ")).unwrap();
    }
    let variable = get(&d.co_simulation, "canHandleVariableCommunicationStepSize") == Some("true");
    writeln!(
        s,
        "<li>Communication steps: {}.</li>",
        if variable {
            "any step size, changing from step to step"
        } else {
            "a fixed step size"
        }
    )
    .unwrap();
    if let Some(ts) = d.variables.iter().find(|v| v.name() == "Ts") {
        writeln!(
            s,
            "<li><code>Ts</code>: {}</li>",
            esc(ts.get("description").unwrap_or(""))
        )
        .unwrap();
    }
    s.push_str(&feedthrough(d));
    s.push_str("</ul>\n");
    s
}

/// Which outputs depend directly on inputs (ModelStructure's dependencies): the others in one item.
fn feedthrough(d: &Description) -> String {
    let code = |v: &Variable| format!("<code>{}</code>", esc(v.name()));
    let (mut held, mut s) = (Vec::new(), String::new());
    for (a, deps) in &d.outputs {
        let key = get(a, "index").or_else(|| get(a, "valueReference"));
        let Some(v) = key.and_then(|k| d.lookup(k)) else {
            continue;
        };
        let Some(deps) = deps else {
            writeln!(
                s,
                "<li>{} may depend directly on every input (no dependencies declared).</li>",
                code(v)
            )
            .unwrap();
            continue;
        };
        let inputs: Vec<String> = deps
            .split_whitespace()
            .filter_map(|k| d.lookup(k))
            .filter(|x| x.causality() == "input")
            .map(code)
            .collect();
        if inputs.is_empty() {
            held.push(code(v));
        } else {
            writeln!(
                s,
                "<li>{} depends directly on {}: after they are set it has the value for the current \
                 communication point.</li>",
                code(v),
                inputs.join(", ")
            )
            .unwrap();
        }
    }
    if !held.is_empty() {
        writeln!(
            s,
            "<li>{} depend on the inputs only through a step: they change in a step, and after the step to \
             a communication point they hold that point's values.</li>",
            held.join(", ")
        )
        .unwrap();
    }
    s
}

/// The variables, by causality, in a table each.
fn variables(d: &Description) -> String {
    let mut s = String::from("<h2>Variables</h2>\n");
    for (causality, title) in [
        ("input", "Inputs"),
        ("output", "Outputs"),
        ("parameter", "Parameters"),
        ("independent", "Independent variable"),
        ("local", "Local variables"),
        ("calculatedParameter", "Calculated parameters"),
    ] {
        let vars: Vec<&Variable> = d.with_causality(causality).collect();
        if vars.is_empty() {
            continue;
        }
        writeln!(
            s,
            "<h3>{title}</h3>\n<table>\n<tr><th>name</th><th>type</th><th>causality</th>\
             <th>variability</th><th>unit</th><th>start</th><th>range</th><th>description</th></tr>"
        )
        .unwrap();
        for v in vars {
            s.push_str(&row(v));
        }
        s.push_str("</table>\n");
    }
    s
}

fn row(v: &Variable) -> String {
    let cell = |k: &str| esc(v.get(k).unwrap_or(""));
    let range = match (v.get("min"), v.get("max")) {
        (None, None) => String::new(),
        (lo, hi) => format!(
            "[{}, {}]",
            esc(lo.unwrap_or("-inf")),
            esc(hi.unwrap_or("inf"))
        ),
    };
    let variability = v.get("variability").unwrap_or("continuous");
    format!(
        "<tr><td><code>{}</code></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>\
         <td>{}</td></tr>\n",
        cell("name"),
        esc(&v.ty),
        cell("causality"),
        esc(variability),
        cell("unit"),
        cell("start"),
        range,
        cell("description"),
    )
}

/// A minimal FMPy run: the default experiment, a sine on the first input (the others at their start
/// values), every output recorded.
fn example(d: &Description) -> String {
    let file = format!("{}.fmu", d.name());
    let num = |k: &str, default: &str| get(&d.default_experiment, k).unwrap_or(default).to_string();
    let (start, stop, step) = (
        num("startTime", "0"),
        num("stopTime", "10"),
        num("stepSize", "1"),
    );
    let outputs: Vec<String> = d
        .with_causality("output")
        .map(|v| format!("{:?}", v.name()))
        .collect();
    let input = d
        .with_causality("input")
        .find(|v| matches!(v.ty.as_str(), "Real" | "Float64"));
    let mut py = String::from("import numpy as np\nfrom fmpy import simulate_fmu\n\n");
    let mut call = format!(
        "result = simulate_fmu({file:?}, start_time={start}, stop_time={stop}, output_interval={step},\n"
    );
    if let Some(u) = input {
        let name = u.name();
        writeln!(
            py,
            "t = np.arange({start}, {stop} + {step}, {step})\n\
             signals = np.zeros(len(t), dtype=[(\"time\", float), ({name:?}, float)])\n\
             signals[\"time\"] = t\n\
             signals[{name:?}] = np.sin(2 * np.pi * t / 50)  # the other inputs keep their start values"
        )
        .unwrap();
        call.push_str("                      input=signals,\n");
    }
    write!(
        py,
        "{call}                      output=[{}])\nprint(result[-5:])\n",
        outputs.join(", ")
    )
    .unwrap();
    format!(
        "<h2>Example</h2>\n<p>With <a href=\"https://github.com/CATIA-Systems/FMPy\">FMPy</a> \
         (<code>pip install fmpy</code>), in the folder of <code>{}</code>:</p>\n\
         <pre class=\"example\"><code>{}</code></pre>\n",
        esc(&file),
        esc(&py)
    )
}

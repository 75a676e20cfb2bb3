//! Forged FMU states, the same for both FMI versions: a real serialised state (an instance that took one
//! sample, at t = 1) with one field changed at a time, for every rule the layer checks a state against, and
//! the check that each forgery is refused with a log line naming the field while the instance keeps its
//! state and stays usable. tests/fmi_state_machine.rs runs it through the FMI 2.0 exports,
//! tests/fmi3_exports.rs through the FMI 3.0 ones ([`StateApi`]).

use super::Kind;
use serde_json::Value;

/// fmi2OK / fmi3OK and fmi2Error / fmi3Error (the same numbers in both versions).
pub const OK: u32 = 0;
pub const ERROR: u32 = 3;

/// What the forgery check needs of an instance, in one FMI version.
pub trait StateApi: Sized {
    /// An instance of `kind` in step complete that took one sample with u = 0.7 (from t = 0 to t = 1).
    fn running(kind: Kind, name: &str) -> Self;
    /// The instance's current FMU state, serialised (got, serialised and freed).
    fn save(&mut self) -> Vec<u8>;
    /// Deserialise `bytes` into a new FMU state (freed again if made): the status, and the last log line.
    fn deserialize(&mut self, bytes: &[u8]) -> (u32, String);
    /// Deserialise `bytes` and restore the instance to them (both must succeed).
    fn restore(&mut self, bytes: &[u8]);
    fn step(&mut self, t: f64, h: f64) -> u32;
    /// Every Real variable's value, in table order.
    fn reals(&self) -> Vec<f64>;
}

/// A serialised state with one field changed.
pub struct Forgery {
    /// What was changed, for the failure message.
    pub what: String,
    /// What the refusal's log line names (the field, or its rule's words).
    pub names: &'static str,
    pub bytes: Vec<u8>,
}

/// Stands for a value written as raw JSON text (numbers JSON cannot hold, such as 1e999).
const RAW: &str = "@@forged value@@";

/// JSON pointer to the first object key `key` under `at` (depth first, keys in sorted order).
fn find(v: &Value, at: &str, key: &str) -> Option<String> {
    match v.pointer(at)? {
        Value::Object(m) => {
            if m.contains_key(key) {
                return Some(format!("{at}/{key}"));
            }
            m.keys().find_map(|k| find(v, &format!("{at}/{k}"), key))
        }
        Value::Array(a) => (0..a.len()).find_map(|i| find(v, &format!("{at}/{i}"), key)),
        _ => None,
    }
}

/// The forgeries one state admits: `base` parsed, changed by `edit` at the pointer, serialised.
struct Forger {
    base: Value,
    out: Vec<Forgery>,
}

impl Forger {
    fn at(&self, key: &str) -> String {
        find(&self.base, "", key).unwrap_or_else(|| panic!("no field {key} in {}", self.base))
    }

    /// Set the value at `ptr` to the raw JSON text `raw`.
    fn raw(&mut self, ptr: &str, raw: &str, names: &'static str) {
        let mut v = self.base.clone();
        *v.pointer_mut(ptr).unwrap_or_else(|| panic!("no {ptr}")) = Value::from(RAW);
        let text = v.to_string().replacen(&format!("\"{RAW}\""), raw, 1);
        self.out.push(Forgery {
            what: format!("{ptr} = {raw}"),
            names,
            bytes: text.into_bytes(),
        });
    }

    /// Change the value at `ptr` with `edit`.
    fn edit(&mut self, ptr: &str, what: &str, names: &'static str, edit: impl FnOnce(&mut Value)) {
        let mut v = self.base.clone();
        edit(v.pointer_mut(ptr).unwrap_or_else(|| panic!("no {ptr}")));
        self.out.push(Forgery {
            what: format!("{ptr}: {what}"),
            names,
            bytes: v.to_string().into_bytes(),
        });
    }

    /// Add `d` to the number at `ptr` (a count stays an integer).
    fn shift(&mut self, ptr: &str, d: f64, names: &'static str) {
        self.edit(ptr, &format!("{d:+}"), names, |x| {
            *x = match x.as_u64() {
                Some(n) => Value::from(n + d as u64),
                None => Value::from(x.as_f64().unwrap() + d),
            }
        });
    }

    /// The layer's fields: instance state, times, sample count, latched inputs.
    fn layer(&mut self) {
        for s in ["StartEnd", "StepInProgress", "StepCanceled", "Fatal"] {
            self.raw("/layer/state", &format!("\"{s}\""), "instance state");
        }
        self.raw("/layer/state", "\"Running\"", "'state'");
        self.raw("/layer/start_time", "1e999", "'start_time'");
        self.raw("/layer/start_time", "1.5", "start_time");
        self.raw("/layer/stop_time", "-1.0", "stop_time");
        self.raw("/layer/stop_time", "0.5", "stop_time");
        self.raw("/layer/stop_time", "1e999", "'stop_time'");
        self.raw("/layer/time", "-0.5", "time");
        self.raw("/layer/time", "1e999", "'time'");
        self.raw("/layer/time", "null", "'time'");
        self.raw("/layer/time", "3.0", "time");
        for k in ["0", "2", "18446744073709551615"] {
            self.raw("/layer/samples", k, "samples");
        }
        self.raw("/layer/samples", "-1", "'samples'");
        self.raw("/layer/latched_inputs", "[]", "latched_inputs");
        self.edit("/layer/latched_inputs", "one more", "latched_inputs", |v| {
            v.as_array_mut().unwrap().push(Value::from(0.0))
        });
        self.raw("/layer/latched_inputs", "[1e999, 0.0]", "'latched_inputs'");
        self.raw("/layer/latched_inputs", "[null, 0.0]", "'latched_inputs'");
    }

    /// BacklashPlant's model: the gaps (as set and in the running plant), the plant's sample counter, its
    /// history and outputs.
    fn plant(&mut self) {
        self.raw("/model/params/backlash/c1", "-0.5", "c1");
        let inner = format!("{}/params/backlash", self.at("plant"));
        self.shift(&format!("{inner}/c1"), 0.25, "gaps");
        self.shift(&format!("{inner}/c2"), 0.25, "gaps");
        let k = self.at("k");
        self.shift(&k, 1.0, "samples");
        self.raw(&self.at("head"), "999", "head");
        let out = self.at("out");
        self.raw(&format!("{out}/y"), "1e999", "'y'");
        self.raw("/model/u", "1e999", "'u'");
        self.raw("/model/ts", "0.0", "Ts");
    }

    /// MrgiaEstimator's model: the estimates (with the gaps c1, c2 at the end), the covariance, the noise
    /// estimate, the sample counter and the settings (the initial gap c_init) of the running estimator.
    fn estimator(&mut self) {
        let theta = self.at("theta");
        self.edit(&theta, "one entry fewer", "'theta'", |v| {
            v.as_array_mut().unwrap().pop();
        });
        let n = self.base.pointer(&theta).unwrap().as_array().unwrap().len();
        self.raw(&format!("{theta}/0"), "1e999", "'theta'");
        self.raw(&format!("{theta}/{}", n - 1), "1e999", "'theta'");
        self.raw(&format!("{theta}/{}", n - 2), "null", "'theta'");
        let p = self.at("p");
        self.raw(&format!("{p}/1"), "1e999", "'p'");
        self.edit(&p, "one entry fewer", "'p'", |v| {
            v.as_array_mut().unwrap().pop();
        });
        // Entry (1, 0) changed, (0, 1) not.
        self.shift(&format!("{p}/1"), 0.5, "covariance P is not symmetric");
        self.raw(&self.at("sigma"), "-1.0", "sigma");
        self.raw(&self.at("sigma"), "0.0", "sigma");
        let samples = format!("{}/samples", self.at("core").rsplit_once('/').unwrap().0);
        self.shift(&samples, 1.0, "samples");
        let cfg = format!("{}/c_init", self.at("cfg"));
        self.shift(&cfg, 0.125, "c_init");
        self.raw("/model/na", "99", "na");
        self.raw("/model/y", "1e999", "'y'");
    }
}

/// Every forgery of `bytes`, a state of `kind` (an instance that took one sample, at t = 1).
pub fn forgeries(kind: Kind, bytes: &[u8]) -> Vec<Forgery> {
    let mut f = Forger {
        base: serde_json::from_slice(bytes).expect("an FMU state is JSON"),
        out: Vec::new(),
    };
    f.layer();
    match kind {
        Kind::Plant => f.plant(),
        Kind::Estimator => f.estimator(),
    }
    f.out
}

/// `bytes` as JSON with the instance state left out (a refused call moves the instance to error).
fn without_instance_state(bytes: &[u8]) -> Value {
    let mut v: Value = serde_json::from_slice(bytes).unwrap();
    v["layer"]["state"] = Value::Null;
    v
}

/// Every forgery of a real state of `kind` is refused with fmiError and a log line naming its field; the
/// instance keeps its state (its state serialises the same, its values are the same) and, restored, steps
/// like an untouched twin. Returns the forgeries that broke this, one line each.
pub fn forged_states_are_refused<F: StateApi>(kind: Kind) -> Vec<String> {
    let mut f = F::running(kind, "forged");
    let mut twin = F::running(kind, "twin");
    let bytes = f.save();
    let (own, log) = f.deserialize(&bytes);
    assert_eq!(own, OK, "{kind:?}: its own state was refused: {log}");
    let before = twin.reals();
    assert_eq!(twin.step(1.0, 1.0), OK);
    let after = twin.reals();
    let mut failures = Vec::new();
    for forged in forgeries(kind, &bytes) {
        let (status, log) = f.deserialize(&forged.bytes);
        if status != ERROR || !log.contains(forged.names) {
            failures.push(format!(
                "{kind:?} {}: status {status}, log {log:?} (expected {ERROR} and {:?})",
                forged.what, forged.names
            ));
        }
        let kept = without_instance_state(&f.save()) == without_instance_state(&bytes);
        if !kept || f.reals() != before {
            failures.push(format!(
                "{kind:?} {}: the instance's state changed",
                forged.what
            ));
        }
        f.restore(&bytes);
        let stepped = f.step(1.0, 1.0);
        if stepped != OK || f.reals() != after {
            failures.push(format!(
                "{kind:?} {}: restored, it steps unlike its twin",
                forged.what
            ));
        }
        f.restore(&bytes);
    }
    failures
}

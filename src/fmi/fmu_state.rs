//! FMU states: their serialised form and the registry of those an instance handed out.
//!
//! A saved FMU state is a deep, pointer-free copy: the serialised bytes themselves, JSON with a format tag,
//! the FMU's GUID, the core's [`LayerState`] and the model. Bytes from outside (a file, another process, the
//! other FMU) are checked before they are used: header, JSON, layer state, and the model's own consistency.
//!
//! The importer holds FMU states as raw pointers. The ones an instance issued live in its [`Issued`]
//! registry of Boxes; a pointer from the importer is compared with the registry before it is read through or
//! freed, so a foreign or freed pointer is refused, never dereferenced.

use super::model::Model;
use super::state::State;
use super::timing::LayerState;
use super::vars::{Causality, check_value, input_indices};
use serde::{Deserialize, Serialize};

/// Tag at the start of every saved or serialised FMU state.
const STATE_FORMAT: &str = "backlash-fmu-state/2";

#[derive(Serialize)]
struct EnvelopeRef<'a, M> {
    format: &'a str,
    guid: &'a str,
    layer: &'a LayerState,
    model: &'a M,
}

#[derive(Deserialize)]
struct Envelope<M> {
    format: String,
    guid: String,
    layer: LayerState,
    model: M,
}

#[derive(Deserialize)]
struct Header {
    format: String,
    guid: String,
}

/// The layer states an FMU state may carry: those a sequence of legal calls can leave an instance in.
fn check_layer(l: &LayerState, inputs: usize) -> Result<(), String> {
    if !matches!(
        l.state,
        State::Instantiated
            | State::InitializationMode
            | State::StepComplete
            | State::StepFailed
            | State::Terminated
            | State::Error
    ) {
        return Err(format!(
            "the FMU state claims the instance state '{}', which no sequence of calls produces",
            l.state.name()
        ));
    }
    if !l.start_time.is_finite() {
        return Err(format!(
            "the FMU state's start_time {} is not finite",
            l.start_time
        ));
    }
    if let Some(s) = l.stop_time
        && !(s.is_finite() && s >= l.start_time)
    {
        return Err(format!(
            "the FMU state's stop_time {s} is not finite or lies before its start_time {}",
            l.start_time
        ));
    }
    if !l.time.is_finite() || l.time < l.start_time {
        return Err(format!(
            "the FMU state's time {} is not finite or lies before its start_time {}",
            l.time, l.start_time
        ));
    }
    let v = &l.latched_inputs;
    if v.len() != inputs || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "the FMU state's latched_inputs are not {inputs} finite numbers ({} numbers)",
            v.len()
        ));
    }
    Ok(())
}

/// The model is initialised exactly in the states after initialization mode (either in the error state),
/// and it has processed as many samples as the layer counts.
fn check_model_samples(l: &LayerState, model: Option<u64>) -> Result<(), String> {
    let after = matches!(
        l.state,
        State::StepComplete | State::StepFailed | State::Terminated
    );
    let before = matches!(l.state, State::Instantiated | State::InitializationMode);
    match model {
        None if after => Err(format!(
            "the FMU state's model is not initialised, but its state is '{}'",
            l.state.name()
        )),
        Some(_) if before => Err(format!(
            "the FMU state's model is initialised, but its state is '{}'",
            l.state.name()
        )),
        Some(k) if k != l.samples => Err(format!(
            "the FMU state's model has processed {k} samples, its samples field says {}",
            l.samples
        )),
        None if l.samples != 0 => Err(format!(
            "the FMU state's samples field says {}, but its model is not initialised",
            l.samples
        )),
        _ => Ok(()),
    }
}

/// Why `bytes` do not parse as an FMU state, with the field the parser stopped in when there is one.
fn corrupted(bytes: &[u8], e: &serde_json::Error) -> String {
    match field_at(bytes, e.line(), e.column()) {
        Some(f) => format!(
            "the FMU state is truncated or corrupted ({e}; the parser stopped in field '{f}')"
        ),
        None => format!("the FMU state is truncated or corrupted ({e})"),
    }
}

/// The last object key before `line`:`column` (1-based, as serde_json reports positions) in `bytes`.
fn field_at(bytes: &[u8], line: usize, column: usize) -> Option<&str> {
    let line_start = match line {
        0 | 1 => 0,
        n => {
            bytes
                .iter()
                .enumerate()
                .filter(|(_, b)| **b == b'\n')
                .nth(n - 2)?
                .0
                + 1
        }
    };
    let before = &bytes[..(line_start + column).min(bytes.len())];
    let colon = before.windows(2).rposition(|w| w == b"\":")?;
    let open = before[..colon].iter().rposition(|&b| b == b'"')?;
    std::str::from_utf8(&before[open + 1..colon]).ok()
}

fn check_header(bytes: &[u8], guid: &str, model: &str) -> Result<(), String> {
    let h: Header = serde_json::from_slice(bytes).map_err(|e| corrupted(bytes, &e))?;
    if h.format != STATE_FORMAT {
        return Err(format!(
            "the FMU state has format '{}', expected '{STATE_FORMAT}'",
            h.format
        ));
    }
    if h.guid != guid {
        return Err(format!(
            "the FMU state belongs to another FMU (GUID {}), not to {model} (GUID {guid})",
            h.guid
        ));
    }
    Ok(())
}

/// Parse and check an FMU state of model `M`: header, JSON, layer state, and the model's own consistency.
pub fn parse<M: Model>(bytes: &[u8]) -> Result<(LayerState, M), String> {
    check_header(bytes, M::GUID, M::MODEL_IDENTIFIER)?;
    let env: Envelope<M> = serde_json::from_slice(bytes).map_err(|e| corrupted(bytes, &e))?;
    debug_assert!(env.format == STATE_FORMAT && env.guid == M::GUID);
    check_layer(&env.layer, input_indices(M::VARIABLES).len())?;
    env.model
        .check_restored()
        .map_err(|e| format!("the FMU state is inconsistent: {e}"))?;
    check_model_samples(&env.layer, env.model.samples())?;
    env.layer.check_clock(env.model.sample_period())?;
    for (i, v) in M::VARIABLES.iter().enumerate() {
        if v.causality != Causality::Output {
            check_value(v, &env.model.get(M::var(i)))
                .map_err(|e| format!("the FMU state is inconsistent: {e}"))?;
        }
    }
    Ok((env.layer, env.model))
}

/// Serialise `model` with the core's `layer` into FMU-state bytes, which are checked to restore.
pub fn save<M: Model>(model: &M, layer: &LayerState) -> Result<Vec<u8>, String> {
    let bytes = serde_json::to_vec(&EnvelopeRef {
        format: STATE_FORMAT,
        guid: M::GUID,
        layer,
        model,
    })
    .map_err(|e| format!("cannot save the FMU state: {e}"))?;
    // Hand out only states that can be restored (JSON has no NaN or infinity, for one).
    parse::<M>(&bytes)
        .map_err(|e| format!("cannot save the FMU state: it would not restore: {e}"))?;
    Ok(bytes)
}

/// A saved FMU state: a deep, pointer-free copy (the serialised bytes themselves).
pub struct SavedState {
    pub bytes: Vec<u8>,
}

/// The FMU states an instance issued and has not freed: the only pointers the state functions accept.
#[derive(Default)]
pub struct Issued(Vec<*mut SavedState>);

impl Issued {
    /// Store `saved` where the importer's `*FMUstate` points: in the state it names if that is one this
    /// registry issued (the standard's "overwrite a previous state"), else in a new one. Returns the pointer
    /// to hand out. A non-NULL pointer this registry did not issue is refused, never dereferenced.
    pub fn issue(
        &mut self,
        existing: *mut SavedState,
        saved: SavedState,
    ) -> Result<*mut SavedState, String> {
        if existing.is_null() {
            let p = Box::into_raw(Box::new(saved));
            self.0.push(p);
            return Ok(p);
        }
        let q = self.find(existing)?;
        // SAFETY: `q` comes from the registry: a live Box this registry made and has not freed.
        unsafe { *q = saved };
        Ok(q)
    }

    /// The state behind `p` if this registry issued it and has not freed it.
    pub fn get(&self, p: *const SavedState) -> Result<&SavedState, String> {
        let q = self.find(p)?;
        // SAFETY: `q` comes from the registry: a live Box this registry made; it lives while `self` holds it,
        // and nothing writes it while the shared borrow of `self` lasts.
        Ok(unsafe { &*q })
    }

    /// Free a state this registry issued.
    pub fn free(&mut self, p: *mut SavedState) -> Result<(), String> {
        let q = self.find(p)?;
        self.0.retain(|&r| r != q);
        // SAFETY: `q` was in the registry (a live Box from `issue`) and is now out of it: freed once.
        drop(unsafe { Box::from_raw(q) });
        Ok(())
    }

    /// The registry's entry equal to `p`: pointers are compared, never read through.
    fn find(&self, p: *const SavedState) -> Result<*mut SavedState, String> {
        if let Some(&q) = self.0.iter().find(|&&q| std::ptr::eq(q, p)) {
            Ok(q)
        } else {
            Err(format!(
                "FMUstate {p:p} is not a state this instance issued (or it was freed): pass the FMU state \
                 that the get or deserialize function returned (for the free function, its address)"
            ))
        }
    }
}

impl Drop for Issued {
    /// States the importer did not free belong to the instance and go with it.
    fn drop(&mut self) {
        for p in self.0.drain(..) {
            // SAFETY: every registered pointer is a live Box from `issue`, freed nowhere else.
            drop(unsafe { Box::from_raw(p) });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A layer as one sample from t = 0 leaves it, with a stop time and one input.
    fn running() -> LayerState {
        LayerState {
            state: State::StepComplete,
            start_time: 0.0,
            stop_time: Some(10.0),
            time: 1.0,
            samples: 1,
            latched: false,
            latched_inputs: vec![0.5],
        }
    }

    /// Each rule of `check_layer` on its own, with the values JSON cannot carry too (NaN, infinities: a
    /// state's bytes cannot hold them today, the check must not depend on that), and the limits a legal run
    /// reaches accepted (time at the start time, stop time at the start time).
    #[test]
    fn check_layer_refuses_each_field_by_name() {
        type Edit = fn(&mut LayerState);
        let refused: [(Edit, &str); 17] = [
            (|l| l.state = State::StartEnd, "'start/end'"),
            (|l| l.state = State::StepInProgress, "'step in progress'"),
            (|l| l.state = State::StepCanceled, "'step canceled'"),
            (|l| l.state = State::Fatal, "'fatal'"),
            (|l| l.start_time = f64::NAN, "start_time NaN"),
            (|l| l.start_time = f64::NEG_INFINITY, "start_time -inf"),
            (|l| l.stop_time = Some(f64::NAN), "stop_time NaN"),
            (|l| l.stop_time = Some(f64::INFINITY), "stop_time inf"),
            (|l| l.stop_time = Some(-0.5), "stop_time -0.5"),
            (|l| l.time = f64::NAN, "time NaN"),
            (|l| l.time = f64::INFINITY, "time inf"),
            (|l| l.time = -0.5, "time -0.5"),
            (
                |l| l.latched_inputs.clear(),
                "latched_inputs are not 1 finite numbers (0",
            ),
            (
                |l| l.latched_inputs.push(0.0),
                "latched_inputs are not 1 finite numbers (2",
            ),
            (|l| l.latched_inputs[0] = f64::NAN, "latched_inputs"),
            (|l| l.latched_inputs[0] = f64::INFINITY, "latched_inputs"),
            (
                |l| {
                    l.start_time = f64::NAN;
                    l.stop_time = Some(1.0);
                },
                "start_time NaN",
            ),
        ];
        assert_eq!(check_layer(&running(), 1), Ok(()));
        for (edit, names) in refused {
            let mut l = running();
            edit(&mut l);
            let e = check_layer(&l, 1).expect_err(names);
            assert!(e.contains(names), "{e:?} does not name {names:?}");
        }
        let accepted: [Edit; 9] = [
            |l| l.state = State::Instantiated,
            |l| l.state = State::InitializationMode,
            |l| l.state = State::StepFailed,
            |l| l.state = State::Terminated,
            |l| l.state = State::Error,
            |l| l.stop_time = None,
            |l| l.stop_time = Some(0.0),
            |l| l.time = 0.0,
            |l| l.stop_time = Some(1.0),
        ];
        for edit in accepted {
            let mut l = running();
            edit(&mut l);
            assert_eq!(check_layer(&l, 1), Ok(()), "{l:?}");
        }
    }

    /// The model is initialised exactly after initialization mode, and counts the layer's samples.
    #[test]
    fn check_model_samples_ties_the_model_to_the_layer() {
        let at = |state, samples| LayerState {
            state,
            samples,
            ..running()
        };
        let refused = [
            (at(State::StepComplete, 1), None, "not initialised"),
            (at(State::StepFailed, 0), None, "not initialised"),
            (at(State::Terminated, 0), None, "not initialised"),
            (at(State::Instantiated, 0), Some(0), "is initialised"),
            (at(State::InitializationMode, 0), Some(0), "is initialised"),
            (at(State::StepComplete, 1), Some(2), "processed 2 samples"),
            (at(State::Error, 3), Some(2), "processed 2 samples"),
            (at(State::Error, 3), None, "samples field says 3"),
        ];
        for (l, model, names) in refused {
            let e = check_model_samples(&l, model).expect_err(names);
            assert!(e.contains(names), "{e:?} does not name {names:?}");
        }
        for (l, model) in [
            (at(State::StepComplete, 1), Some(1)),
            (at(State::Error, 0), None),
            (at(State::Error, 2), Some(2)),
            (at(State::Instantiated, 0), None),
        ] {
            assert_eq!(check_model_samples(&l, model), Ok(()), "{l:?} {model:?}");
        }
    }

    /// The header: the format tag and the GUID must be this FMU's; bytes that are no JSON object are named
    /// as corrupted. A state with the right header passes.
    #[test]
    fn check_header_refuses_another_format_or_fmu() {
        let head = |format: &str, guid: &str| format!(r#"{{"format":"{format}","guid":"{guid}"}}"#);
        assert_eq!(
            check_header(head(STATE_FORMAT, "g").as_bytes(), "g", "M"),
            Ok(())
        );
        for (bytes, names) in [
            (
                head("backlash-fmu-state/1", "g"),
                "format 'backlash-fmu-state/1'",
            ),
            (
                head(STATE_FORMAT, "h"),
                "another FMU (GUID h), not to M (GUID g)",
            ),
            (r#"{"format":"#.to_string(), "truncated or corrupted"),
            (String::new(), "truncated or corrupted"),
        ] {
            let e = check_header(bytes.as_bytes(), "g", "M").expect_err(names);
            assert!(e.contains(names), "{e:?} does not name {names:?}");
        }
    }

    /// The key before a parse error's position: on the first and a later line, and none before any key.
    #[test]
    fn field_at_names_the_key_the_parser_stopped_in() {
        let one = br#"{"a":1,"b":[1,2,x]}"#;
        assert_eq!(field_at(one, 1, 17), Some("b"));
        assert_eq!(field_at(one, 1, 5), Some("a"));
        assert_eq!(field_at(one, 1, 2), None);
        let two = b"{\"a\":1,\n\"c\":nul}";
        assert_eq!(field_at(two, 2, 6), Some("c"));
        // Column 4 is the colon after "c": a line start one or two bytes early would stop at "a".
        assert_eq!(field_at(two, 2, 4), Some("c"));
        assert_eq!(field_at(two, 9, 1), None);
        let e = serde_json::from_slice::<serde_json::Value>(one).unwrap_err();
        assert!(corrupted(one, &e).ends_with("stopped in field 'b')"), "{e}");
    }
}

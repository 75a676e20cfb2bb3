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
    if !l.start_time.is_finite()
        || l.stop_time
            .is_some_and(|s| !(s.is_finite() && s >= l.start_time))
    {
        return Err("the FMU state's start or stop time is invalid".into());
    }
    if !l.time.is_finite() || l.time < l.start_time {
        return Err("the FMU state's time is not finite or lies before its start time".into());
    }
    let v = &l.latched_inputs;
    if v.len() != inputs || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "the FMU state's latched inputs are not {inputs} finite numbers"
        ));
    }
    Ok(())
}

fn check_header(bytes: &[u8], guid: &str, model: &str) -> Result<(), String> {
    let h: Header = serde_json::from_slice(bytes)
        .map_err(|e| format!("the FMU state is truncated or corrupted ({e})"))?;
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
    let env: Envelope<M> = serde_json::from_slice(bytes)
        .map_err(|e| format!("the FMU state is truncated or corrupted ({e})"))?;
    debug_assert!(env.format == STATE_FORMAT && env.guid == M::GUID);
    check_layer(&env.layer, input_indices(M::VARIABLES).len())?;
    env.model
        .check_restored()
        .map_err(|e| format!("the FMU state is inconsistent: {e}"))?;
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

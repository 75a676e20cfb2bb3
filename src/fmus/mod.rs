//! The two FMUs: small adapters from the FMI layer's [`Model`](crate::fmi2::Model) trait to the physics.
//! Variables in, model step, variables out; no numerics here.
//!
//! The variable tables come from modelDescription/*.xml through build.rs. Each adapter matches on the
//! generated `Var` enum exhaustively, so a variable added to the XML and not handled here (or the reverse)
//! fails the build.

include!(concat!(env!("OUT_DIR"), "/model_descriptions.rs"));

pub mod estimator;
pub mod plant;

use crate::fmi2::registry::{Entry, Registry};

/// The FMUs of this crate, registered for the protocol layers (which reach it as `crate::FMUS`): one binary
/// serves both, the layer picks the model by the GUID or instantiation token the importer passes.
pub static REGISTRY: Registry = Registry::new(&[
    Entry::of::<plant::PlantFmu>(),
    Entry::of::<estimator::EstimatorFmu>(),
]);

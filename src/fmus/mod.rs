//! The two FMUs: small adapters from the FMI layer's [`Model`](crate::fmi2::Model) trait to the physics.
//! Variables in, model step, variables out; no numerics here.
//!
//! The variable tables come from modelDescription/*.xml through build.rs. Each adapter matches on the
//! generated `Var` enum exhaustively, so a variable added to the XML and not handled here (or the reverse)
//! fails the build.

include!(concat!(env!("OUT_DIR"), "/model_descriptions.rs"));

pub mod estimator;
pub mod plant;

use crate::fmi2::instance::{Adapter, Slave};

/// The model whose GUID the importer passed to fmi2Instantiate (one binary serves both FMUs), or why there
/// is none (the message names the GUIDs this binary knows).
pub fn instantiate(guid: &str) -> Result<Box<dyn Slave>, String> {
    if guid == backlash_plant::GUID {
        Ok(Box::new(Adapter::<plant::PlantFmu>::new()))
    } else if guid == mrgia_estimator::GUID {
        Ok(Box::new(Adapter::<estimator::EstimatorFmu>::new()))
    } else {
        Err(format!(
            "fmuGUID {guid} matches neither {} nor {}: the modelDescription.xml and the binary do not belong together",
            backlash_plant::GUID,
            mrgia_estimator::GUID
        ))
    }
}

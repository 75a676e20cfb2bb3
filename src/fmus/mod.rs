//! The three FMUs: small adapters from the FMI core's [`Model`](crate::fmi::Model) trait to the physics.
//! Variables in, model step, variables out; no numerics here.
//!
//! The variable tables come from modelDescription/*.xml through build.rs. Each adapter matches on the
//! generated `Var` enum exhaustively, so a variable added to the XML and not handled here (or the reverse)
//! fails the build.

include!(concat!(env!("OUT_DIR"), "/model_descriptions.rs"));

pub mod compensator;
pub mod estimator;
pub mod plant;

use crate::fmi::registry::{Binary, Entry, Fmus, Registry};

/// The FMUs of this crate: one binary serves them all, the protocol layers pick the model by the GUID or
/// instantiation token the importer passes.
pub static REGISTRY: Registry = Registry::new(&[
    Entry::of::<plant::PlantFmu>(),
    Entry::of::<estimator::EstimatorFmu>(),
    Entry::of::<compensator::CompensatorFmu>(),
]);

/// The registration: the seam the FMI core declares, implemented here once.
impl Fmus for Binary {
    fn registry() -> &'static Registry {
        &REGISTRY
    }
}

#[cfg(test)]
mod tests {
    use super::{backlash_compensator, backlash_plant, mrgia_estimator};
    use crate::fmi::registry::registry;

    #[test]
    fn the_seam_serves_each_fmu_by_its_guid_and_refuses_others() {
        let fmus = registry();
        let guids: Vec<&str> = fmus.entries().iter().map(|e| e.guid).collect();
        assert_eq!(
            guids,
            [
                backlash_plant::GUID,
                mrgia_estimator::GUID,
                backlash_compensator::GUID
            ]
        );
        for e in fmus.entries() {
            let slave = fmus.instantiate(e.guid, "fmuGUID").unwrap();
            assert_eq!((slave.guid(), slave.identifier()), (e.guid, e.identifier));
        }
        let err = fmus.instantiate("{0}", "instantiationToken").err().unwrap();
        assert!(
            err.starts_with("instantiationToken {0} matches none"),
            "{err}"
        );
    }
}

//! The built FMUs through the `fmi` crate, an importer nobody here wrote, and the exports' signatures checked
//! against the standard headers as bindgen renders them in `fmi-sys`.
//!
//! Needs `cargo build --release` first (it leaves target/fmu/*.fmu).

use backlash::fmi2::exports::*;
use backlash::fmi2::ffi::Fmi2CallbackFunctions;
use backlash::identify::mrgia::{Mrgia, MrgiaConfig};
use backlash::plant::{Plant, PlantParams};
use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation, Common};
use fmi_sys::fmi2 as sys;
use std::mem::{align_of, offset_of, size_of};
use std::path::PathBuf;

// Every export has exactly the type the standard's header declares (a mismatch does not compile).
const _: sys::fmi2GetTypesPlatformTYPE = Some(fmi2GetTypesPlatform);
const _: sys::fmi2GetVersionTYPE = Some(fmi2GetVersion);
const _: sys::fmi2SetDebugLoggingTYPE = Some(fmi2SetDebugLogging);
const _: sys::fmi2FreeInstanceTYPE = Some(fmi2FreeInstance);
const _: sys::fmi2SetupExperimentTYPE = Some(fmi2SetupExperiment);
const _: sys::fmi2EnterInitializationModeTYPE = Some(fmi2EnterInitializationMode);
const _: sys::fmi2ExitInitializationModeTYPE = Some(fmi2ExitInitializationMode);
const _: sys::fmi2TerminateTYPE = Some(fmi2Terminate);
const _: sys::fmi2ResetTYPE = Some(fmi2Reset);
const _: sys::fmi2GetRealTYPE = Some(fmi2GetReal);
const _: sys::fmi2GetIntegerTYPE = Some(fmi2GetInteger);
const _: sys::fmi2GetBooleanTYPE = Some(fmi2GetBoolean);
const _: sys::fmi2GetStringTYPE = Some(fmi2GetString);
const _: sys::fmi2SetRealTYPE = Some(fmi2SetReal);
const _: sys::fmi2SetIntegerTYPE = Some(fmi2SetInteger);
const _: sys::fmi2SetBooleanTYPE = Some(fmi2SetBoolean);
const _: sys::fmi2SetStringTYPE = Some(fmi2SetString);
const _: sys::fmi2GetFMUstateTYPE = Some(fmi2GetFMUstate);
const _: sys::fmi2SetFMUstateTYPE = Some(fmi2SetFMUstate);
const _: sys::fmi2FreeFMUstateTYPE = Some(fmi2FreeFMUstate);
const _: sys::fmi2SerializedFMUstateSizeTYPE = Some(fmi2SerializedFMUstateSize);
const _: sys::fmi2SerializeFMUstateTYPE = Some(fmi2SerializeFMUstate);
const _: sys::fmi2DeSerializeFMUstateTYPE = Some(fmi2DeSerializeFMUstate);
const _: sys::fmi2GetDirectionalDerivativeTYPE = Some(fmi2GetDirectionalDerivative);
const _: sys::fmi2SetRealInputDerivativesTYPE = Some(fmi2SetRealInputDerivatives);
const _: sys::fmi2GetRealOutputDerivativesTYPE = Some(fmi2GetRealOutputDerivatives);
const _: sys::fmi2DoStepTYPE = Some(fmi2DoStep);
const _: sys::fmi2CancelStepTYPE = Some(fmi2CancelStep);
const _: sys::fmi2GetStatusTYPE = Some(fmi2GetStatus);
const _: sys::fmi2GetRealStatusTYPE = Some(fmi2GetRealStatus);
const _: sys::fmi2GetIntegerStatusTYPE = Some(fmi2GetIntegerStatus);
const _: sys::fmi2GetBooleanStatusTYPE = Some(fmi2GetBooleanStatus);
const _: sys::fmi2GetStringStatusTYPE = Some(fmi2GetStringStatus);
// fmi2Instantiate takes the callback struct, which this crate declares itself: its type differs by name
// only, so the signature is checked with our struct and the struct's layout against the header's below.
const _: unsafe extern "C" fn(
    sys::fmi2String,
    sys::fmi2Type,
    sys::fmi2String,
    sys::fmi2String,
    *const Fmi2CallbackFunctions,
    sys::fmi2Boolean,
    sys::fmi2Boolean,
) -> sys::fmi2Component = fmi2Instantiate;

#[test]
fn callback_struct_has_the_headers_layout() {
    type C = sys::fmi2CallbackFunctions;
    type R = Fmi2CallbackFunctions;
    assert_eq!(size_of::<R>(), size_of::<C>());
    assert_eq!(align_of::<R>(), align_of::<C>());
    assert_eq!(offset_of!(R, logger), offset_of!(C, logger));
    assert_eq!(
        offset_of!(R, allocate_memory),
        offset_of!(C, allocateMemory)
    );
    assert_eq!(offset_of!(R, free_memory), offset_of!(C, freeMemory));
    assert_eq!(offset_of!(R, step_finished), offset_of!(C, stepFinished));
    assert_eq!(
        offset_of!(R, component_environment),
        offset_of!(C, componentEnvironment)
    );
}

/// target/fmu/<name>.fmu, or under $BACKLASH_FMU_DIR when set (as the Python tests do).
fn fmu(name: &str) -> PathBuf {
    let dir = std::env::var_os("BACKLASH_FMU_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/fmu"));
    let p = dir.join(format!("{name}.fmu"));
    assert!(
        p.exists(),
        "{} is missing: run `cargo build --release` first",
        p.display()
    );
    p
}

fn vr(import: &Fmi2Import, name: &str) -> u32 {
    use fmi::traits::FmiImport;
    import
        .model_description()
        .model_variables
        .variables
        .iter()
        .find(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}"))
        .value_reference
}

fn paper_input(n: usize) -> Vec<f64> {
    // Deterministic, bounded, rich enough to engage both borders and the gap.
    (0..n)
        .map(|k| 2.4 * ((k as f64 * 0.7).sin() * (k as f64 * 0.13).cos()))
        .collect()
}

#[test]
fn plant_fmu_steps_like_the_library_through_the_fmi_crate() {
    let import: Fmi2Import = fmi::import::from_path(fmu("BacklashPlant")).unwrap();
    let mut inst = import.instantiate_cs("plant", false, true).unwrap();
    let (u_vr, y_vr, x_vr) = (vr(&import, "u"), vr(&import, "y"), vr(&import, "x"));
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.set_real(&[vr(&import, "noise_std")], &[0.02]).unwrap();
    inst.set_integer(&[vr(&import, "noise_seed")], &[11])
        .unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();

    let u = paper_input(500);
    let mut params = PlantParams::PAPER;
    params.noise_std = 0.02;
    params.noise_seed = 11;
    let want = Plant::simulate(params, &u).unwrap();
    for (k, (&uk, w)) in u.iter().zip(&want).enumerate() {
        let mut out = [0.0; 2];
        inst.get_real(&[y_vr, x_vr], &mut out).unwrap();
        // Same code behind both: bit-identical.
        assert_eq!(out, [w.y, w.x], "sample {k}");
        inst.set_real(&[u_vr], &[uk]).unwrap();
        inst.do_step(k as f64, 1.0, true).unwrap();
    }
    // A refused step (not from the end of the previous one) comes back as an error, not a crash.
    assert!(inst.do_step(499.5, 0.5, true).is_err());
}

#[test]
fn estimator_fmu_matches_the_library_through_the_fmi_crate() {
    let import: Fmi2Import = fmi::import::from_path(fmu("MrgiaEstimator")).unwrap();
    let mut inst = import.instantiate_cs("estimator", false, true).unwrap();
    inst.setup_experiment(None, 0.0, None).unwrap();
    inst.enter_initialization_mode().unwrap();
    inst.exit_initialization_mode().unwrap();
    let names = ["a1", "a2", "b0", "m2", "c1", "c2"];
    let vrs: Vec<u32> = names.iter().map(|n| vr(&import, n)).collect();
    let (u_vr, y_vr) = (vr(&import, "u"), vr(&import, "y"));

    let u = paper_input(1500);
    let y: Vec<f64> = Plant::simulate(PlantParams::PAPER, &u)
        .unwrap()
        .iter()
        .map(|o| o.y)
        .collect();
    let mut lib = Mrgia::new(MrgiaConfig::paper(2, 0, 1)).unwrap();
    for k in 0..u.len() {
        inst.set_real(&[u_vr, y_vr], &[u[k], y[k]]).unwrap();
        inst.do_step(k as f64, 1.0, true).unwrap();
        lib.update(u[k], y[k]);
    }
    let mut got = vec![0.0; vrs.len()];
    inst.get_real(&vrs, &mut got).unwrap();
    let e = lib.estimate();
    assert_eq!(got, vec![e.a[0], e.a[1], e.b[0], e.m2, e.c1, e.c2]);
    // Two samples in one step would feed the same sample twice: refused.
    assert!(inst.do_step(1500.0, 2.0, true).is_err());
}

//! The FMUs this repository ships: the file stem of each description in modelDescription/ and the Rust module
//! generated from it. Read by both build scripts (build.rs generates the modules, packaging/build.rs zips the
//! FMUs).

pub const MODELS: [(&str, &str); 3] = [
    ("BacklashPlant", "backlash_plant"),
    ("MrgiaEstimator", "mrgia_estimator"),
    ("BacklashCompensator", "backlash_compensator"),
];

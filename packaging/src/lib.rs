//! Nothing to link: this package exists for its build script, which packages the FMUs of `backlash-fmu`
//! (`target/fmu/<Model>.fmu`, FMI 2.0, and `target/fmu3/<Model>.fmu`, FMI 3.0) in release builds.
//!
//! Why a package of its own: a build script runs before its crate is compiled, and the FMU binary comes from a
//! nested build of the library (build/package.rs says why). Run from the library's own build script, that
//! nested build held back the library's compilation until it had finished; as this package's build script it
//! runs beside it, so `cargo build --release` takes the longer of the two, not their sum.

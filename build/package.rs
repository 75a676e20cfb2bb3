//! Packages the FMUs: builds this crate's cdylib with a nested cargo and zips it with its description.
//!
//! A build script runs before its own crate is compiled, so it cannot see the crate's final shared library.
//! The way around (as substrate-wasm-builder does) is a nested `cargo build --release --lib` of this same
//! package into a separate target directory, guarded by the environment variable `BACKLASH_FMU_NESTED`
//! against recursion. One shared library serves both FMUs: `fmi2Instantiate` picks the model by GUID.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The directory cargo builds into (`target/`), found from OUT_DIR (`target/<profile>/build/<pkg>/out`, or
/// `target/<triple>/<profile>/build/<pkg>/out` when cross-compiling).
pub fn target_dir(out_dir: &Path) -> PathBuf {
    if let Ok(t) = std::env::var("CARGO_TARGET_DIR") {
        let p = PathBuf::from(t);
        return if p.is_absolute() {
            p
        } else {
            PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap()).join(p)
        };
    }
    let build = out_dir
        .ancestors()
        .find(|p| p.file_name().is_some_and(|n| n == "build"))
        .expect("OUT_DIR lies under a 'build' directory");
    let profile_dir = build.parent().expect("profile directory");
    let mut t = profile_dir
        .parent()
        .expect("target directory")
        .to_path_buf();
    if let Ok(triple) = std::env::var("TARGET")
        && t.file_name().is_some_and(|n| n == triple.as_str())
    {
        t = t.parent().unwrap().to_path_buf();
    }
    t
}

/// Build the cdylib with a nested cargo and return the path of the shared library.
pub fn build_cdylib(manifest_dir: &Path, target: &Path) -> Result<PathBuf, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let nested_target = target.join("fmu-build");
    let mut cmd = Command::new(cargo);
    cmd.arg("build")
        .arg("--release")
        .arg("--lib")
        .arg("--manifest-path")
        .arg(manifest_dir.join("Cargo.toml"))
        .arg("--target-dir")
        .arg(&nested_target)
        .env("BACKLASH_FMU_NESTED", "1")
        // The outer cargo's jobserver is not shared: the nested build runs with its own job count.
        .env_remove("MAKEFLAGS")
        .env_remove("CARGO_MAKEFLAGS")
        .env_remove("MFLAGS");
    if std::env::var_os("CARGO_NET_OFFLINE").is_some() {
        cmd.arg("--offline");
    }
    let status = cmd
        .status()
        .map_err(|e| format!("cannot start the nested cargo: {e}"))?;
    if !status.success() {
        return Err(format!(
            "the nested cargo build of the FMU binary failed ({status})"
        ));
    }
    let lib = nested_target.join("release").join("libbacklash.so");
    if !lib.exists() {
        return Err(format!("the nested build did not leave {}", lib.display()));
    }
    Ok(lib)
}

/// Write `<fmu_dir>/<id>.fmu` with binaries/linux64/<id>.so and modelDescription.xml.
pub fn write_fmu(
    fmu_dir: &Path,
    id: &str,
    model_description: &str,
    lib: &Path,
) -> Result<PathBuf, String> {
    std::fs::create_dir_all(fmu_dir).map_err(|e| format!("{}: {e}", fmu_dir.display()))?;
    let path = fmu_dir.join(format!("{id}.fmu"));
    let tmp = fmu_dir.join(format!(".{id}.fmu.tmp"));
    let binary = std::fs::read(lib).map_err(|e| format!("{}: {e}", lib.display()))?;
    let result = (|| -> zip::result::ZipResult<()> {
        let file = std::fs::File::create(&tmp)?;
        let mut zip = zip::ZipWriter::new(file);
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        zip.start_file("modelDescription.xml", opts)?;
        zip.write_all(model_description.as_bytes())?;
        zip.add_directory("binaries/", opts)?;
        zip.add_directory("binaries/linux64/", opts)?;
        zip.start_file(
            format!("binaries/linux64/{id}.so"),
            opts.unix_permissions(0o755),
        )?;
        zip.write_all(&binary)?;
        zip.finish()?;
        Ok(())
    })();
    result.map_err(|e| format!("writing {}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, &path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}

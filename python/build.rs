//! Copies the FMUs that this same cargo build packaged (the dependency `backlash-fmu-packaging` passes their folder as
//! DEP_BACKLASH_FMU_FMU_DIR) into the Python package, `backlash_fmu/fmu` (FMI 2.0) and `backlash_fmu/fmu3`
//! (FMI 3.0, when that build made them), where maturin picks them up as package data. Builds that package no
//! FMUs (debug builds; `BACKLASH_FMU=never`, with a warning) leave the package's folders as they are.

use std::path::{Path, PathBuf};

fn main() {
    let package = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("backlash_fmu");
    println!("cargo:rerun-if-env-changed=DEP_BACKLASH_FMU_FMU_DIR");
    let Some(fmu_dir) = std::env::var_os("DEP_BACKLASH_FMU_FMU_DIR").map(PathBuf::from) else {
        if std::env::var("PROFILE").as_deref() != Ok("release") {
            return;
        }
        println!(
            "cargo:warning=this build packages no FMUs (BACKLASH_FMU=never): the Python \
             package keeps the FMUs it has, if any"
        );
        return;
    };
    let fmu3_dir = fmu_dir.with_file_name("fmu3");
    for (from, to) in [(fmu_dir, "fmu"), (fmu3_dir, "fmu3")] {
        if let Err(e) = sync(&from, &package.join(to)) {
            println!("cargo:warning={e}");
            std::process::exit(1);
        }
    }
}

/// Makes `to` hold exactly the `.fmu` files of `from` (none when `from` does not exist).
fn sync(from: &Path, to: &Path) -> Result<(), String> {
    let fmus = |dir: &Path| -> Result<Vec<PathBuf>, String> {
        if !dir.is_dir() {
            return Ok(vec![]);
        }
        let entries = std::fs::read_dir(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let mut v = vec![];
        for entry in entries {
            let p = entry.map_err(|e| format!("{}: {e}", dir.display()))?.path();
            if p.extension().is_some_and(|x| x == "fmu") {
                v.push(p);
            }
        }
        Ok(v)
    };
    println!("cargo:rerun-if-changed={}", from.display());
    for old in fmus(to)? {
        std::fs::remove_file(&old).map_err(|e| format!("{}: {e}", old.display()))?;
    }
    let new = fmus(from)?;
    if new.is_empty() {
        return Ok(());
    }
    std::fs::create_dir_all(to).map_err(|e| format!("{}: {e}", to.display()))?;
    for f in new {
        println!("cargo:rerun-if-changed={}", f.display());
        let dest = to.join(f.file_name().expect("a file name"));
        std::fs::copy(&f, &dest)
            .map_err(|e| format!("{} -> {}: {e}", f.display(), dest.display()))?;
    }
    // Not `rerun-if-changed` on `to`: this script writes there, so the folder would always look newer than the
    // last run, and every build would run the script and compile the extension again.
    Ok(())
}

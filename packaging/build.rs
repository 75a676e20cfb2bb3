//! Packages `target/fmu/<Model>.fmu` (FMI 2.0) and `target/fmu3/<Model>.fmu` (FMI 3.0) in release builds,
//! around one shared library that exports both APIs, built without the default feature `cli` (see
//! build/package.rs), for this build's platform only (scripts/dist.sh: every platform in one FMU). Set
//! `BACKLASH_FMU=never` to skip packaging, `BACKLASH_FMU=always` to package in debug builds too. On Linux the
//! binary is the portable GLIBC 2.17 build when cargo-zigbuild is installed (`BACKLASH_FMU_PORTABLE=never`
//! skips it, `=require` fails without it); without it the build warns. The descriptions are the ones the
//! library's build script checked and generated its variables from (modelDescription/*.xml; the FMI 3.0
//! text from the same file, build/fmi3.rs).

#[path = "../build/docs.rs"]
mod docs;
#[path = "../build/fmi3.rs"]
#[allow(
    dead_code,
    reason = "the library's build script uses the rest of the module"
)]
mod fmi3;
#[path = "../build/icon.rs"]
mod icon;
#[path = "../build/models.rs"]
mod models;
#[path = "../build/package.rs"]
mod package;
#[path = "../build/ssp.rs"]
mod ssp;

use std::path::{Path, PathBuf};

fn main() {
    let manifest_dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap());
    let root = manifest_dir
        .parent()
        .expect("packaging/ lies in the repository")
        .to_path_buf();
    println!("cargo:rerun-if-env-changed=BACKLASH_FMU");
    if std::env::var_os("BACKLASH_FMU_NESTED").is_some() {
        return;
    }
    let mode = std::env::var("BACKLASH_FMU").unwrap_or_default();
    let release = std::env::var("PROFILE").as_deref() == Ok("release");
    if mode == "never" || (!release && mode != "always") {
        return;
    }
    // The FMU binary is built from the library's sources: rebuild it when any of them changes.
    for path in [
        "src",
        "build",
        "modelDescription",
        "Cargo.toml",
        "Cargo.lock",
    ] {
        println!("cargo:rerun-if-changed={}", root.join(path).display());
    }
    println!("cargo:rerun-if-env-changed=BACKLASH_FMU_PORTABLE");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    let target = package::target_dir(&out_dir, &root);
    let platform = package::Platform::of_build().unwrap_or_else(|e| fail(&e));
    let (lib, portability) =
        package::build_cdylib(&root, &target, &platform).unwrap_or_else(|e| fail(&e));
    if let package::Portability::Unavailable(why) = portability {
        println!(
            "cargo:warning=the FMUs' binary is linked against this machine's GLIBC, not 2.17, and may not load \
             on older Linux: {why}"
        );
    }
    for (stem, _) in models::MODELS {
        let path = root.join("modelDescription").join(format!("{stem}.xml"));
        let text = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| fail(&format!("{}: {e}", path.display())));
        let text3 = fmi3::model_description(stem, &text)
            .unwrap_or_else(|e| fail(&format!("{} (FMI 3.0 description): {e}", path.display())));
        for (dir, xml, folder) in [
            ("fmu", &text, &platform.folder),
            ("fmu3", &text3, &platform.folder3),
        ] {
            let extra = documentation(xml)
                .unwrap_or_else(|e| fail(&format!("{} (documentation): {e}", path.display())));
            package::write_fmu(
                &target.join(dir),
                stem,
                xml,
                &extra,
                &lib,
                &platform,
                folder,
            )
            .unwrap_or_else(|e| fail(&e));
        }
    }
    write_ssp(&root, &target).unwrap_or_else(|e| fail(&e));
    // Dependents (the Python extension, which copies the FMUs into its package) read this as
    // DEP_BACKLASH_FMU_FMU_DIR; the FMI 3.0 variants are in the sibling folder `fmu3`.
    println!("cargo:fmu_dir={}", target.join("fmu").display());
}

/// `target/ssp/BacklashIdentification.ssp`: the FMI 2.0 plant and estimator just packaged, connected
/// (build/ssp.rs).
fn write_ssp(root: &Path, target: &Path) -> Result<(), String> {
    let (plant, estimator) = ("BacklashPlant", "MrgiaEstimator");
    let read = |stem: &str| -> Result<docs::Description, String> {
        let path = root.join("modelDescription").join(format!("{stem}.xml"));
        let text =
            std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        docs::read(&text).map_err(|e| format!("{}: {e}", path.display()))
    };
    let ssd = ssp::ssd(&read(plant)?, &read(estimator)?)
        .map_err(|e| format!("{} (SSP): {e}", ssp::NAME))?;
    let fmu = |stem: &str| target.join("fmu").join(format!("{stem}.fmu"));
    let (p, e) = (fmu(plant), fmu(estimator));
    let path = target.join("ssp").join(format!("{}.ssp", ssp::NAME));
    ssp::write(
        &path,
        &ssd,
        &[(plant, p.as_path()), (estimator, e.as_path())],
    )
}

/// What an FMI tool shows besides the variables, made from the description the FMU carries (FMI 2.0 or 3.0):
/// `documentation/index.html` and the icon (FMI 2.0 `model.png`, FMI 3.0 `terminalsAndIcons/icon.png`).
fn documentation(xml: &str) -> Result<Vec<(String, Vec<u8>)>, String> {
    let d = docs::read(xml)?;
    let icon = icon::png(
        d.with_causality("input").count(),
        d.with_causality("output").count(),
    )?;
    let icon_path = if d.fmi3() {
        "terminalsAndIcons/icon.png"
    } else {
        "model.png"
    };
    Ok(vec![
        (
            "documentation/index.html".to_string(),
            docs::index_html(xml)?.into_bytes(),
        ),
        (icon_path.to_string(), icon),
    ])
}

fn fail(msg: &str) -> ! {
    eprintln!("error: {msg}");
    println!("cargo:warning={msg}");
    std::process::exit(1);
}

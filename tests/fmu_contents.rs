//! What an FMI tool shows of every packaged FMU besides its variables: `documentation/index.html` names every
//! variable of the FMU's own description and has the timing and an example; the icon (FMI 2.0 `model.png`,
//! FMI 3.0 `terminalsAndIcons/icon.png`) is a PNG that decodes. Every FMU found in target/fmu and target/fmu3
//! (and target/dist, when scripts/dist.sh has run), so an FMU added to the build is checked by construction.
//!
//! Needs `cargo build --release` first.

use std::io::Read;
use std::path::{Path, PathBuf};

fn target() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("target")
}

/// The packaged FMUs: every .fmu of the folders the build (and dist.sh) fills.
fn fmus() -> Vec<PathBuf> {
    let mut found = Vec::new();
    for dir in ["fmu", "fmu3", "dist/fmi2", "dist/fmi3"] {
        let Ok(entries) = std::fs::read_dir(target().join(dir)) else {
            assert!(
                dir.starts_with("dist"),
                "target/{dir} is missing: run `cargo build --release`"
            );
            continue;
        };
        found.extend(
            entries
                .map(|e| e.unwrap().path())
                .filter(|p| p.extension().is_some_and(|x| x == "fmu")),
        );
    }
    assert!(
        found.len() >= 4,
        "expected the FMUs of target/fmu and target/fmu3, found {found:?}"
    );
    found
}

fn entry(fmu: &Path, name: &str) -> Vec<u8> {
    let mut zip = zip::ZipArchive::new(std::fs::File::open(fmu).unwrap()).unwrap();
    let mut file = zip
        .by_name(name)
        .unwrap_or_else(|e| panic!("{}: no {name}: {e}", fmu.display()));
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes).unwrap();
    bytes
}

/// The names of the variables in a description's ModelVariables (FMI 2.0 ScalarVariables or FMI 3.0 typed
/// elements; their type elements and children carry no name).
fn variable_names(xml: &str) -> Vec<String> {
    let start = xml.find("<ModelVariables>").expect("ModelVariables");
    let end = xml
        .find("</ModelVariables>")
        .expect("end of ModelVariables");
    xml[start..end]
        .split(" name=\"")
        .skip(1)
        .map(|s| s[..s.find('"').unwrap()].to_string())
        .collect()
}

#[test]
fn every_fmu_documents_every_variable_of_its_description() {
    for fmu in fmus() {
        let xml = String::from_utf8(entry(&fmu, "modelDescription.xml")).unwrap();
        let html = String::from_utf8(entry(&fmu, "documentation/index.html")).unwrap();
        let names = variable_names(&xml);
        assert!(names.len() > 3, "{}: variables {names:?}", fmu.display());
        for name in &names {
            assert!(
                html.contains(&format!("<td><code>{name}</code></td>")),
                "{}: documentation/index.html has no row for '{name}'",
                fmu.display()
            );
        }
        for part in ["<h2>Timing</h2>", "<h2>Example</h2>", "simulate_fmu"] {
            assert!(html.contains(part), "{}: no {part}", fmu.display());
        }
    }
}

#[test]
fn every_fmu_has_an_icon_that_decodes() {
    for fmu in fmus() {
        let xml = String::from_utf8(entry(&fmu, "modelDescription.xml")).unwrap();
        let path = if xml.contains("fmiVersion=\"3.0\"") {
            "terminalsAndIcons/icon.png"
        } else {
            "model.png"
        };
        let bytes = entry(&fmu, path);
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap_or_else(|e| panic!("{}: {path} is no PNG: {e}", fmu.display()));
        let mut pixels = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut pixels).unwrap();
        assert!(
            info.width >= 64 && info.height >= 64,
            "{}: {path} is {}x{}",
            fmu.display(),
            info.width,
            info.height
        );
        assert_eq!(info.color_type, png::ColorType::Rgba);
        let opaque = pixels.chunks(4).filter(|p| p[3] == 255).count();
        let share = opaque as f64 / (info.width * info.height) as f64;
        assert!(
            (0.3..0.99).contains(&share),
            "{}: {path} is {share:.2} opaque: nothing or everything drawn",
            fmu.display()
        );
    }
}

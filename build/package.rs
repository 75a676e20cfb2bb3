//! Packages the FMUs (packaging/build.rs): builds the library's cdylib with a nested cargo and zips it with
//! its description.
//!
//! A build script runs before its crate is compiled, so no build script sees the library's final shared
//! library. The way around (as substrate-wasm-builder does) is a nested `cargo build --profile fmu --lib
//! --no-default-features` of the library (the FMUs alone: plant, estimators, FMI layers; no plots, FFT or
//! thread pool) into a separate target directory, guarded by the environment variable `BACKLASH_FMU_NESTED`
//! against recursion. It builds for this build's target only; scripts/dist.sh builds the same library for the
//! other platforms and merges them into the same FMUs. One shared library serves both FMUs in both FMI versions: it exports the fmi2* and the
//! fmi3* functions (disjoint names), and `fmi2Instantiate` / `fmi3InstantiateCoSimulation` pick the model by
//! GUID (instantiation token). One nested build instead of two, and the two versions cannot drift apart.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The directory cargo builds into (`target/`), found from OUT_DIR (`target/<profile>/build/<pkg>/out`, or
/// `target/<triple>/<profile>/build/<pkg>/out` when cross-compiling); a relative `CARGO_TARGET_DIR` is taken
/// from the workspace's `root`.
pub fn target_dir(out_dir: &Path, root: &Path) -> PathBuf {
    if let Ok(t) = std::env::var("CARGO_TARGET_DIR") {
        let p = PathBuf::from(t);
        return if p.is_absolute() { p } else { root.join(p) };
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

/// Where the FMU standard puts a platform's binary, from the target cargo builds for.
pub struct Platform {
    /// The target triple (`TARGET`).
    pub triple: String,
    /// The FMI 2.0 platform folder: linux64, win64, darwin64 (or the 32-bit ones).
    pub folder: String,
    /// The FMI 3.0 platform tuple: x86_64-linux, aarch64-darwin, x86_64-windows, ...
    pub folder3: String,
    /// File name of the cdylib cargo writes, and the extension the FMU's binary takes.
    pub cdylib: String,
    pub extension: &'static str,
    /// Linux with the GNU C library: the portable build links against GLIBC 2.17 there.
    pub glibc: bool,
}

impl Platform {
    /// The platform of the current build (build-script environment).
    pub fn of_build() -> Result<Self, String> {
        let var = |n: &str| std::env::var(n).map_err(|_| format!("cargo did not set {n}"));
        let (os, bits) = (
            var("CARGO_CFG_TARGET_OS")?,
            var("CARGO_CFG_TARGET_POINTER_WIDTH")?,
        );
        let env = std::env::var("CARGO_CFG_TARGET_ENV").unwrap_or_default();
        let arch = match var("CARGO_CFG_TARGET_ARCH")?.as_str() {
            "x86" => "x86".to_string(),
            other => other.to_string(),
        };
        let (folder, prefix, extension) = match os.as_str() {
            "linux" => ("linux", "lib", "so"),
            "windows" => ("win", "", "dll"),
            "macos" => ("darwin", "lib", "dylib"),
            other => {
                return Err(format!(
                    "the FMI 2.0 standard has no platform folder for {other}"
                ));
            }
        };
        // FMI 3.0 names the operating systems in full: x86_64-windows, not x86_64-win.
        let os3 = if os == "windows" { "windows" } else { folder };
        Ok(Self {
            triple: var("TARGET")?,
            folder: format!("{folder}{bits}"),
            folder3: format!("{arch}-{os3}"),
            cdylib: format!("{prefix}backlash.{extension}"),
            extension,
            glibc: os == "linux" && env == "gnu",
        })
    }
}

/// `cargo-zigbuild`, if installed: on PATH or in this checkout's `.venv` (where scripts/setup.sh puts it).
fn zigbuild(manifest_dir: &Path) -> Option<PathBuf> {
    let venv = manifest_dir
        .join(".venv")
        .join("bin")
        .join("cargo-zigbuild");
    if venv.is_file() {
        return Some(venv);
    }
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("cargo-zigbuild"))
        .find(|p| p.is_file())
}

/// The nested `cargo build` (or `cargo-zigbuild zigbuild`) of the library alone.
fn nested(
    program: &Path,
    sub: &str,
    manifest_dir: &Path,
    target_dir: &Path,
    triple: &str,
) -> Command {
    let mut cmd = Command::new(program);
    cmd.arg(sub)
        .arg("--profile")
        .arg("fmu")
        .arg("--package")
        .arg("backlash-fmu")
        .arg("--lib")
        // The FMUs alone: without the feature `cli` (plots, fonts, FFT, thread pool; see Cargo.toml).
        .arg("--no-default-features")
        .arg("--manifest-path")
        .arg(manifest_dir.join("Cargo.toml"))
        .arg("--target-dir")
        .arg(target_dir)
        .arg("--target")
        .arg(triple)
        // Only the environment a shell gives cargo: the outer build's own variables (its jobserver, flags,
        // a linker or C compiler a wheel builder sets for its target, profile overrides) are not for the FMU
        // binary, and any difference would make the nested build start over each time the outer one
        // changes (a `cargo build` after a wheel build).
        .env_clear()
        .envs(std::env::vars_os().filter(|(k, _)| k.to_str().is_some_and(passed_to_nested)))
        .env("BACKLASH_FMU_NESTED", "1");
    if std::env::var_os("CARGO_NET_OFFLINE").is_some() {
        cmd.arg("--offline");
    }
    cmd
}

/// The variables the nested build keeps: where the toolchain and its caches are, the network settings a
/// download needs, the locale and the temporary directory.
fn passed_to_nested(name: &str) -> bool {
    const EXACT: [&str; 13] = [
        "PATH",
        "HOME",
        "USER",
        "TMPDIR",
        "LANG",
        "LC_ALL",
        "CARGO_HOME",
        "RUSTUP_HOME",
        "RUSTUP_TOOLCHAIN",
        "SSL_CERT_FILE",
        "SSL_CERT_DIR",
        "NO_PROXY",
        "no_proxy",
    ];
    const PREFIXES: [&str; 5] = [
        "CARGO_NET_",
        "CARGO_HTTP_",
        "CARGO_REGISTRIES_",
        "HTTP",
        "http",
    ];
    EXACT.contains(&name) || PREFIXES.iter().any(|p| name.starts_with(p))
}

fn run(mut cmd: Command, what: &str) -> Result<(), String> {
    let status = cmd
        .status()
        .map_err(|e| format!("cannot start {what}: {e}"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{what} of the FMU binary failed ({status})"))
    }
}

/// How the FMU binary was built: whether it is the portable (GLIBC 2.17) build, and if not, why.
pub enum Portability {
    Portable,
    NotApplicable,
    Unavailable(String),
}

/// Build the cdylib with a nested cargo and return the path of the shared library. On Linux with glibc the
/// binary is linked against GLIBC 2.17 with `cargo-zigbuild` (and zig) when they are installed, so that it
/// loads on old distributions; otherwise with this machine's C library, and the caller warns.
/// `BACKLASH_FMU_PORTABLE=never` skips the portable build, `=require` fails without it.
pub fn build_cdylib(
    manifest_dir: &Path,
    target: &Path,
    platform: &Platform,
) -> Result<(PathBuf, Portability), String> {
    let cargo = PathBuf::from(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    let nested_target = target.join("fmu-build");
    let mode = std::env::var("BACKLASH_FMU_PORTABLE").unwrap_or_default();
    let lib_in = |dir: &str| nested_target.join(dir).join("fmu").join(&platform.cdylib);
    let zig = zigbuild(manifest_dir).filter(|_| platform.glibc && mode != "never");
    let portability = if let Some(zig) = zig {
        let glibc_target = format!("{}.2.17", platform.triple);
        let mut cmd = nested(
            &zig,
            "zigbuild",
            manifest_dir,
            &nested_target,
            &glibc_target,
        );
        // cargo-zigbuild runs `cargo`, and finds zig as `python3 -m ziglang` next to itself (the venv's).
        let mut path = vec![cargo.parent().map(Path::to_path_buf).unwrap_or_default()];
        path.extend(zig.parent().map(Path::to_path_buf));
        path.extend(std::env::split_paths(
            &std::env::var_os("PATH").unwrap_or_default(),
        ));
        cmd.env(
            "PATH",
            std::env::join_paths(path).map_err(|e| e.to_string())?,
        );
        match run(cmd, "cargo-zigbuild (the portable GLIBC 2.17 build)") {
            Ok(()) => Portability::Portable,
            Err(e) if mode == "require" => return Err(e),
            Err(e) => Portability::Unavailable(e),
        }
    } else if !platform.glibc {
        Portability::NotApplicable
    } else if mode == "require" {
        return Err(
            "BACKLASH_FMU_PORTABLE=require, but cargo-zigbuild is not installed \
                    (bash scripts/setup.sh installs it)"
                .into(),
        );
    } else if mode == "never" {
        Portability::Unavailable("BACKLASH_FMU_PORTABLE=never".into())
    } else {
        Portability::Unavailable(
            "cargo-zigbuild is not installed (bash scripts/setup.sh installs it with zig)".into(),
        )
    };
    let lib = if matches!(portability, Portability::Portable) {
        lib_in(&platform.triple)
    } else {
        let cmd = nested(
            &cargo,
            "build",
            manifest_dir,
            &nested_target,
            &platform.triple,
        );
        run(cmd, "the nested cargo build")?;
        lib_in(&platform.triple)
    };
    if !lib.exists() {
        return Err(format!("the nested build did not leave {}", lib.display()));
    }
    Ok((lib, portability))
}

/// Write `<fmu_dir>/<id>.fmu` with binaries/<folder>/<id>.<ext>, modelDescription.xml and the `extra` files
/// (archive path, contents: the documentation and the icon) (`folder`: the platform folder of the FMI
/// version, [`Platform::folder`] or [`Platform::folder3`]).
pub fn write_fmu(
    fmu_dir: &Path,
    id: &str,
    model_description: &str,
    extra: &[(String, Vec<u8>)],
    lib: &Path,
    platform: &Platform,
    folder: &str,
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
        for (name, bytes) in extra {
            if let Some((dir, _)) = name.rsplit_once('/') {
                zip.add_directory(format!("{dir}/"), opts)?;
            }
            zip.start_file(name.as_str(), opts)?;
            zip.write_all(bytes)?;
        }
        zip.add_directory("binaries/", opts)?;
        zip.add_directory(format!("binaries/{folder}/"), opts)?;
        zip.start_file(
            format!("binaries/{folder}/{id}.{}", platform.extension),
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

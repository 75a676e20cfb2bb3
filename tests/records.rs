//! Where a measured record is: the one function the tests, benches and examples share (benches and examples
//! include this file with `#[path = "../tests/records.rs"] mod records;`).
//!
//! The records are not part of the repository (data/*/README.md says where each comes from): the fetch step,
//! `python3 scripts/fetch_data.py`, puts them into data/; `BACKLASH_DATA`, when set, names another folder with
//! the same layout. The Python side's twin is scripts/data_records.py.

use std::path::PathBuf;

/// The command that puts the records into data/ (printed when one is missing).
pub const FETCH_COMMAND: &str = "python3 scripts/fetch_data.py";

/// The folder the records are read from: `BACKLASH_DATA` when set, otherwise the repository's data/.
pub fn data_dir() -> PathBuf {
    match std::env::var_os("BACKLASH_DATA") {
        Some(dir) if !dir.is_empty() => PathBuf::from(dir),
        _ => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data"),
    }
}

/// The path of the record `name` (as in data/, e.g. `brfd/KocaeliDBE_36lb.csv`), or an error naming the
/// record, where it was looked for and the command that fetches it.
pub fn find_record(name: &str) -> Result<PathBuf, String> {
    let dir = data_dir();
    let path = dir.join(name);
    if path.is_file() {
        return Ok(path);
    }
    Err(format!(
        "the measured record {name} is not in {} (looked for {}): run `{FETCH_COMMAND}` first \
         (or `{FETCH_COMMAND} --from DIR` with a folder that holds the records; BACKLASH_DATA names \
         another folder to read them from)",
        dir.display(),
        path.display()
    ))
}

/// [`find_record`] for a test or bench: a missing record fails it with that error (never a silent skip).
pub fn record(name: &str) -> PathBuf {
    find_record(name).unwrap_or_else(|e| panic!("{e}"))
}

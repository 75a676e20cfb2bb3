//! The integration tests, as modules of one test binary: each file beside this one is a module here, so the
//! crate and its dependencies are linked into one executable instead of one per file (the largest part of
//! building the tests was linking the same crate a dozen times). Two files stay binaries of their own, because
//! they measure memory: `tests/fmu_memory.rs` installs a counting global allocator, which must not count the
//! other tests' allocations, and `tests/cli_hostile.rs` reads the peak RSS of the program it starts, which on
//! Linux includes the RSS of the test process that spawned it (the child shares the parent's memory until it
//! execs, and the kernel keeps that high-water mark): a parent running every other test beside it made a
//! 2,000,000-row run look 7 MiB larger than a 200,000-row one.
//!
//! Run one file's tests by its module path: `cargo test --release --test integration fmi_fuzz::`.

mod common;
// Where a measured record is (data/ or BACKLASH_DATA); benches and examples include the same file.
mod records;
mod records_found;

mod cli_records;
mod cli_stream;
mod diagnose_agree;
mod diagnose_hostile;
mod diagnose_input_evidence;
mod diagnose_structure;
mod fmi3_exports;
mod fmi_fuzz;
mod fmi_state_machine;
mod fmi_threads;
mod fmi_timing;
mod fmu_compensator;
mod fmu_contents;
mod fmu_import;
mod frequency_real;

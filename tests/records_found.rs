//! The one function that finds a measured record (tests/records.rs; its tests live here because benches and
//! examples include that file, and a bench without the test harness would carry them unused).

use crate::records::{FETCH_COMMAND, find_record, record};

#[test]
fn a_missing_record_is_an_error_naming_it_and_the_fetch_command() {
    let e = find_record("no_such_folder/no_such_record.csv").unwrap_err();
    assert!(e.contains("no_such_folder/no_such_record.csv"), "{e}");
    assert!(e.contains(FETCH_COMMAND), "{e}");
}

#[test]
fn the_records_the_tests_read_are_found() {
    for name in [
        "brfd/char_0.5Hz_36lb_1in.csv",
        "dc_generator/dc_generator.csv",
    ] {
        assert!(record(name).is_file(), "{name}");
    }
}

//! Paper 003 on the measured damper (brfd/char_0.5Hz_36lb_1in.csv of data/, 14,337 samples) against the
//! output-error fit of the same record: the ratio to watch is `identify frequency` (window, every degree,
//! verdict) over `identify oe` (the paper 000 structure declared, default starts), both as the library runs
//! them for the command line.
//!
//! `cargo bench --bench frequency`

use backlash::identify::frequency::SineRecord;
use backlash::identify::frequency::analysis::{AnalysisOptions, analyse};
use backlash::identify::oe::{OeConfig, fit};
use backlash::io::Table;
use criterion::{Criterion, criterion_group, criterion_main};
use std::hint::black_box;

#[path = "../tests/records.rs"]
mod records;

fn frequency_against_oe(c: &mut Criterion) {
    let path = records::record("brfd/char_0.5Hz_36lb_1in.csv");
    let table = Table::read(&path, &["t", "u", "y"]).expect("the damper record reads");
    let col = |name| table.column(name).expect("read above");
    let (t, u, y) = (col("t"), col("u"), col("y"));
    let rec = SineRecord {
        time: t,
        u: Some(u),
        y,
    };
    let mut g = c.benchmark_group("damper record, 14,337 samples");
    g.sample_size(10);
    g.bench_function("identify oe (na 2, nb 0, delay 1): the baseline", |b| {
        b.iter(|| fit(&OeConfig::new(2, 0, 1), black_box(u), y))
    });
    g.bench_function(
        "identify frequency (window, degrees 1 to 6, verdict)",
        |b| b.iter(|| analyse(black_box(&rec), &AnalysisOptions::default())),
    );
    g.bench_function("identify frequency --degree 3", |b| {
        let opts = AnalysisOptions {
            degree: Some(3),
            ..AnalysisOptions::default()
        };
        b.iter(|| analyse(black_box(&rec), &opts))
    });
    g.finish();
}

criterion_group!(benches, frequency_against_oe);
criterion_main!(benches);

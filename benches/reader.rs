//! The CSV reader against the parsers it could use, on the same 200,000-row file in memory (`time,u,y`, the
//! shape of scripts/mrgia_speed.py's record: a sample count and two random values at full precision). Each
//! alternative parses every field of every row and sums the values (so that nothing is optimised away):
//! the project's reader (`RowReader`: lines, UTF-8, field count, numbers, an increasing time column), the
//! fields split by hand and parsed by `f64::from_str`, by `fast-float2` and by `lexical-core`, and the `csv`
//! crate's records parsed by `fast-float2`. Throughput in rows.
//!
//! `cargo bench --bench reader`

use std::io::Cursor;
use std::path::Path;

use backlash::io::RowReader;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand_core::{Rng, SeedableRng};
use std::hint::black_box;

const ROWS: usize = 200_000;

fn file() -> Vec<u8> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut uniform = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 4.8 - 2.4;
    let mut text = String::from("time,u,y\n");
    for k in 0..ROWS {
        let (u, y) = (uniform(), uniform());
        text.push_str(&format!("{k},{u},{y}\n"));
    }
    text.into_bytes()
}

/// Every field of every data line, split by hand, through `parse`.
fn fields(bytes: &[u8], parse: impl Fn(&[u8]) -> f64) -> f64 {
    let mut sum = 0.0;
    for line in bytes.split(|&b| b == b'\n').skip(1) {
        for field in line.split(|&b| b == b',') {
            if !field.is_empty() {
                sum += parse(field);
            }
        }
    }
    sum
}

fn readers(c: &mut Criterion) {
    let bytes = file();
    let mut g = c.benchmark_group("200,000 rows time,u,y");
    g.throughput(Throughput::Elements(ROWS as u64));
    g.sample_size(20);
    g.bench_function("RowReader (the project's reader, all checks)", |b| {
        b.iter(|| {
            let mut r = RowReader::new(
                Cursor::new(black_box(&bytes)),
                Path::new("bench.csv"),
                &["time", "u", "y"],
            )
            .expect("a header");
            let mut sum = 0.0;
            while let Some(row) = r.next_row().expect("valid rows") {
                sum += row[0] + row[1] + row[2];
            }
            sum
        })
    });
    g.bench_function("fields by hand, f64::from_str", |b| {
        b.iter(|| {
            fields(black_box(&bytes), |f| {
                std::str::from_utf8(f)
                    .expect("ASCII")
                    .parse::<f64>()
                    .expect("a number")
            })
        })
    });
    g.bench_function("fields by hand, fast-float2", |b| {
        b.iter(|| {
            fields(black_box(&bytes), |f| {
                fast_float2::parse::<f64, _>(f).expect("a number")
            })
        })
    });
    g.bench_function("fields by hand, lexical-core", |b| {
        b.iter(|| {
            fields(black_box(&bytes), |f| {
                lexical_core::parse::<f64>(f).expect("a number")
            })
        })
    });
    g.bench_function("csv crate records, fast-float2", |b| {
        b.iter(|| {
            let mut r = csv::Reader::from_reader(black_box(&bytes[..]));
            let mut rec = csv::ByteRecord::new();
            let mut sum = 0.0;
            while r.read_byte_record(&mut rec).expect("valid rows") {
                for f in rec.iter() {
                    sum += fast_float2::parse::<f64, _>(f).expect("a number");
                }
            }
            sum
        })
    });
    g.finish();
}

criterion_group!(benches, readers);
criterion_main!(benches);

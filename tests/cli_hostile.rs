//! The command line under hostile input (the data-file rules of docs/INTERFACE.md).
//!
//! Every malformed file is refused with a non-zero exit, nothing on stdout, and a message on stderr that
//! names the file and, where the fault has one, the line and the column: empty file, header only, missing
//! or misnamed column, duplicate column, non-numeric cell, NaN, infinities, overflowing numbers,
//! non-increasing time, ragged rows, invalid UTF-8, a missing file, a directory. `backlash simulate IN -o
//! OUT` leaves no OUT and no temporary file after a failure (and an existing OUT untouched), and
//! `identify mrgia --trace T` writes no T.
//!
//! Large input: `identify mrgia` reads its file in one streaming pass. Generated files of 2e5 and 2e6 rows
//! (2e4 and 4e5 in a debug build) go through `backlash identify mrgia --json --trace T --plot P`; the peak
//! resident memory of the larger run (`ru_maxrss` of the child, from wait4) must be within 4 MiB of the
//! smaller's and under 64 MiB. `one_gigabyte_file_in_bounded_memory` (ignored; scripts/compliance.sh runs
//! it) does the same on a 1 GB file.
#![cfg(target_os = "linux")]

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_backlash");

/// A fresh directory under the system temp dir, removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new(tag: &str) -> TempDir {
        static N: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let p = std::env::temp_dir().join(format!(
            "backlash-cli-hostile-{}-{tag}-{n}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
    /// A fresh directory under `base`, removed on drop.
    fn under(base: &Path, tag: &str) -> TempDir {
        let p = base.join(format!("backlash-cli-hostile-{}-{tag}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
    fn file(&self, name: &str, content: &[u8]) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, content).unwrap();
        p
    }
    fn entries(&self) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn run(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run backlash")
}

fn identify(file: &Path, extra: &[&str]) -> Output {
    let mut a: Vec<&std::ffi::OsStr> =
        vec!["identify".as_ref(), "mrgia".as_ref(), file.as_os_str()];
    for s in ["--na", "2", "--nb", "0", "--delay", "1", "--json"] {
        a.push(s.as_ref());
    }
    for s in extra {
        a.push(s.as_ref());
    }
    run(&a)
}

fn simulate(input: &Path, output: &Path) -> Output {
    run(&[
        "simulate".as_ref(),
        input.as_os_str(),
        "-o".as_ref(),
        output.as_os_str(),
    ])
}

/// Expect a refusal whose stderr contains every piece of `want`.
fn refused(out: &Output, want: &[&str], ctx: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success(),
        "{ctx}: accepted; stdout {}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(
        out.stdout.is_empty(),
        "{ctx}: stdout not empty on failure: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    for w in want {
        assert!(err.contains(w), "{ctx}: stderr lacks {w:?}:\n{err}");
    }
}

/// Three valid rows, lines 2 to 4 after the header (a faulty row appended to them is line 5).
const OK_ROWS: &str = "0,0.1,0\n1,0.2,0.1\n2,0.3,0.2\n";

/// (case, content, pieces the message must contain besides the file name).
type Case = (&'static str, Vec<u8>, Vec<&'static str>);

/// Every case, in the order their files are numbered.
fn hostile_cases() -> Vec<Case> {
    [
        header_cases(),
        cell_cases(),
        time_cases(),
        ragged_row_cases(),
        byte_cases(),
    ]
    .into_iter()
    .flatten()
    .collect()
}

/// The header: no data at all, a missing, misnamed or duplicate column.
fn header_cases() -> Vec<Case> {
    vec![
        ("empty", b"".to_vec(), vec!["empty"]),
        ("blank line only", b"\n".to_vec(), vec!["empty"]),
        ("header only", b"time,u,y\n".to_vec(), vec!["no data rows"]),
        (
            "missing column",
            "time,u\n0,1\n".as_bytes().to_vec(),
            vec!["line 1", "'y'"],
        ),
        (
            "misnamed column",
            format!("Time,u,y\n{OK_ROWS}").into_bytes(),
            vec!["line 1", "'time'"],
        ),
        (
            "duplicate column",
            "time,u,y,u\n0,1,2,3\n".as_bytes().to_vec(),
            vec!["line 1", "'u'", "twice"],
        ),
    ]
}

/// A data cell that is not a finite number.
fn cell_cases() -> Vec<Case> {
    vec![
        (
            "non-numeric cell",
            format!("time,u,y\n{OK_ROWS}3,abc,0.4\n").into_bytes(),
            vec!["line 5", "column 'u'", "'abc'"],
        ),
        (
            "empty cell",
            format!("time,u,y\n{OK_ROWS}3,,0.4\n").into_bytes(),
            vec!["line 5", "column 'u'"],
        ),
        (
            "quoted number",
            format!("time,u,y\n{OK_ROWS}3,\"1.0\",0.4\n").into_bytes(),
            vec!["line 5", "column 'u'"],
        ),
        (
            "NaN",
            format!("time,u,y\n{OK_ROWS}3,0.1,NaN\n").into_bytes(),
            vec!["line 5", "column 'y'", "NaN"],
        ),
        (
            "nan lower case",
            format!("time,u,y\n{OK_ROWS}3,nan,1\n").into_bytes(),
            vec!["line 5", "column 'u'"],
        ),
        (
            "infinity",
            format!("time,u,y\n{OK_ROWS}3,0.1,-inf\n").into_bytes(),
            vec!["line 5", "column 'y'"],
        ),
        (
            "overflow to infinity",
            format!("time,u,y\n{OK_ROWS}3,1e999,1\n").into_bytes(),
            vec!["line 5", "column 'u'", "'1e999' overflows a 64-bit float"],
        ),
    ]
}

/// A time that is not a number or does not increase.
fn time_cases() -> Vec<Case> {
    vec![
        (
            "NaN time",
            format!("time,u,y\n{OK_ROWS}NaN,0,1\n").into_bytes(),
            vec!["line 5", "column 'time'"],
        ),
        (
            "equal time",
            format!("time,u,y\n{OK_ROWS}2,0.1,1\n").into_bytes(),
            vec!["line 5", "column 'time'", "does not increase"],
        ),
        (
            "decreasing time",
            format!("time,u,y\n{OK_ROWS}1.5,0.1,1\n").into_bytes(),
            vec!["line 5", "column 'time'", "does not increase"],
        ),
        (
            "decreasing time, columns reordered",
            "y,time,u\n0,0,0\n0,1,0\n0,0.5,0\n".as_bytes().to_vec(),
            vec!["line 4", "column 'time'"],
        ),
    ]
}

/// A row with fewer or more fields than the header.
fn ragged_row_cases() -> Vec<Case> {
    vec![
        (
            "ragged row, short",
            format!("time,u,y\n{OK_ROWS}3,0.1\n").into_bytes(),
            vec!["line 5", "column 3 ('y'): missing", "2 fields", "3"],
        ),
        (
            "ragged row, two short",
            format!("time,u,y\n{OK_ROWS}3\n").into_bytes(),
            vec!["line 5", "column 2 ('u'): missing", "1 fields"],
        ),
        (
            "ragged row, short in an ignored column",
            "time,u,y,note\n0,0.1,0,a\n1,0.2,0.1\n".as_bytes().to_vec(),
            vec!["line 3", "column 4 ('note'): missing"],
        ),
        (
            "ragged row, long",
            format!("time,u,y\n{OK_ROWS}3,0.1,1,7\n").into_bytes(),
            vec!["line 5", "column 4: extra field '7'", "4 fields"],
        ),
        (
            "trailing comma",
            "time,u,y\n0,1,2,\n".as_bytes().to_vec(),
            vec!["line 2", "column 4: extra field ''", "4 fields"],
        ),
    ]
}

/// Bytes that are not UTF-8, and a line too long to be CSV.
fn byte_cases() -> Vec<Case> {
    vec![
        (
            "invalid UTF-8 in a cell",
            [format!("time,u,y\n{OK_ROWS}3,0.").as_bytes(), b"\xe91,1\n"].concat(),
            vec!["line 5", "byte 5", "not valid UTF-8"],
        ),
        (
            "invalid UTF-8 in the header",
            b"time,u,y\xff\n0,1,2\n".to_vec(),
            vec!["line 1", "byte 9", "not valid UTF-8"],
        ),
        (
            "no line end for 2 MiB (not a CSV file)",
            [b"time,u,y\n0,1,2\n".as_slice(), &[b'7'; 2 << 20]].concat(),
            vec!["line 3", "longer than 1048576 bytes"],
        ),
    ]
}

#[test]
fn malformed_files_are_refused_naming_file_line_and_column() {
    let dir = TempDir::new("cases");
    for (i, (case, content, want)) in hostile_cases().into_iter().enumerate() {
        let f = dir.file(&format!("case{i}.csv"), &content);
        let name = f.display().to_string();
        let mut want_all = vec![name.as_str()];
        want_all.extend(want.iter().copied());
        let out = identify(&f, &[]);
        refused(&out, &want_all, &format!("identify mrgia: {case}"));
        // simulate needs only time,u: skip the cases about y.
        let about_y = want.iter().any(|w| w.contains("'y'"));
        if !about_y {
            let target = dir.0.join(format!("out{i}.csv"));
            let out = simulate(&f, &target);
            refused(&out, &want_all, &format!("simulate: {case}"));
            assert!(
                !target.exists(),
                "simulate: {case}: {} written",
                target.display()
            );
        }
    }
    // Nothing but the inputs is left in the directory: no output, no temporary file.
    let left = dir.entries();
    assert!(left.iter().all(|n| n.starts_with("case")), "{left:?}");
}

#[test]
fn missing_file_directory_and_invalid_utf8() {
    let dir = TempDir::new("io");
    let missing = dir.0.join("nope.csv");
    refused(
        &identify(&missing, &[]),
        &[&missing.display().to_string(), "cannot read"],
        "missing file",
    );
    refused(
        &identify(&dir.0, &[]),
        &[&dir.0.display().to_string()],
        "a directory",
    );
    let f = dir.file("latin1.csv", b"time,u,y\n0,1,2\n1,\xe9,3\n");
    let out = identify(&f, &[]);
    refused(
        &out,
        &[&f.display().to_string(), "line 3, byte 3: not valid UTF-8"],
        "invalid UTF-8",
    );
}

#[test]
fn simulate_leaves_no_output_and_no_temp_file_after_a_failure() {
    let dir = TempDir::new("atomic");
    let good = dir.file("good.csv", b"time,u\n0,0.5\n1,1.5\n2,2.5\n3,-1\n");
    let bad = dir.file("bad.csv", b"time,u\n0,0.5\n1,x\n");
    let out_path = dir.0.join("out.csv");
    // A failure with no previous output: nothing appears.
    refused(
        &simulate(&bad, &out_path),
        &["bad.csv", "line 3"],
        "bad input",
    );
    assert!(!out_path.exists());
    // A good run writes it.
    let ok = simulate(&good, &out_path);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let before = std::fs::read(&out_path).unwrap();
    assert!(before.starts_with(b"time,u,x,w,y\n"));
    // A later failure leaves the previous result as it was.
    refused(&simulate(&bad, &out_path), &["bad.csv"], "bad input again");
    assert_eq!(std::fs::read(&out_path).unwrap(), before);
    // Invalid parameters: refused before anything is written.
    let other = dir.0.join("other.csv");
    let out = run(&[
        "simulate".as_ref(),
        good.as_os_str(),
        "-o".as_ref(),
        other.as_os_str(),
        "--m1".as_ref(),
        "-1".as_ref(),
    ]);
    assert!(!out.status.success());
    assert!(!other.exists());
    // The output path is a directory: the rename fails, the temporary file is removed.
    let sub = dir.0.join("sub");
    std::fs::create_dir(&sub).unwrap();
    std::fs::write(sub.join("keep"), b"x").unwrap();
    let out = simulate(&good, &sub);
    assert!(!out.status.success(), "writing over a non-empty directory");
    // The output directory does not exist.
    let nowhere = dir.0.join("no/such/dir/out.csv");
    assert!(!simulate(&good, &nowhere).status.success());
    assert!(!dir.0.join("no").exists());
    let left = dir.entries();
    assert_eq!(left, ["bad.csv", "good.csv", "out.csv", "sub"], "{left:?}");
    // identify with --trace on a bad file writes no trace.
    let trace = dir.0.join("trace.csv");
    let bad3 = dir.file("bad3.csv", b"time,u,y\n0,1,2\n0,1,2\n");
    refused(
        &identify(&bad3, &["--trace", trace.to_str().unwrap()]),
        &["bad3.csv", "line 3", "column 'time'"],
        "identify --trace",
    );
    assert!(!trace.exists());
    let left = dir.entries();
    assert!(!left.iter().any(|n| n.contains(".tmp")), "{left:?}");
}

#[test]
fn blank_lines_crlf_bom_and_extra_columns_are_accepted() {
    let dir = TempDir::new("lenient");
    let f = dir.file(
        "ok.csv",
        b"\xef\xbb\xbfcomment,y,time,u\r\nx,0,0,1\r\n\r\ny,0.1,1,2\r\nz,0.2,2,3\r\n",
    );
    let out = identify(&f, &[]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("\"samples\":3"), "{text}");
}

/// `struct rusage` of Linux: two `timeval`s, then 14 `long`s, the first `ru_maxrss` (KiB).
#[repr(C)]
struct RUsage {
    utime: [std::ffi::c_long; 2],
    stime: [std::ffi::c_long; 2],
    maxrss: std::ffi::c_long,
    rest: [std::ffi::c_long; 13],
}

unsafe extern "C" {
    fn wait4(pid: i32, status: *mut i32, options: i32, rusage: *mut RUsage) -> i32;
}

/// Run a child to its end; its output, its peak resident set size in KiB (`ru_maxrss` of this very child,
/// from `wait4`, so nothing is missed between polls) and the wall time.
#[expect(
    clippy::zombie_processes,
    reason = "the child is reaped by wait4, which std cannot do"
)]
fn run_measured(mut cmd: Command) -> (Output, u64, Duration) {
    use std::io::Read;
    use std::os::unix::process::ExitStatusExt;
    let t0 = Instant::now();
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut v = Vec::new();
            r.read_to_end(&mut v).map(|_| v)
        })
    };
    let stdout = drain(Box::new(child.stdout.take().unwrap()));
    let stderr = drain(Box::new(child.stderr.take().unwrap()));
    let pid = i32::try_from(child.id()).unwrap();
    let mut status = 0i32;
    let mut ru = RUsage {
        utime: [0; 2],
        stime: [0; 2],
        maxrss: 0,
        rest: [0; 13],
    };
    loop {
        // SAFETY: `pid` is this process's child, not yet reaped (std reaps only in wait/try_wait, never
        // called on it); `status` and `ru` are valid for writes and `ru` has the kernel's layout.
        let r = unsafe { wait4(pid, &mut status, 0, &mut ru) };
        if r == pid {
            break;
        }
        let e = std::io::Error::last_os_error();
        assert_eq!(e.kind(), std::io::ErrorKind::Interrupted, "wait4: {e}");
    }
    let took = t0.elapsed();
    let out = Output {
        status: std::process::ExitStatus::from_raw(status),
        stdout: stdout.join().unwrap().unwrap(),
        stderr: stderr.join().unwrap().unwrap(),
    };
    (out, u64::try_from(ru.maxrss).unwrap(), took)
}

/// Write `rows` rows of plant data (time,u,y), or, with `rows` = None, as many as make `bytes` bytes; return
/// the rows written and the file's size in bytes. The u,y text of a block of rows is formatted once and
/// repeated (the time k counts on), so that a 1 GB file takes seconds, not tens of seconds.
fn write_large(path: &Path, rows: Option<u64>, bytes: u64) -> (u64, u64) {
    const BLOCK: u64 = 1 << 16;
    let mut y_prev = 0.0f64;
    let block: Vec<String> = (0..BLOCK)
        .map(|k| {
            let u = 2.4 * ((k as f64) * 0.7).sin() * ((k as f64) * 0.13).cos();
            // A cheap backlash-like output: enough for the estimator to have work to do.
            let x = 0.8 * u;
            let y = if x > y_prev + 0.5 {
                x - 0.5
            } else if x < y_prev - 1.0 {
                1.5 * (x + 1.0)
            } else {
                y_prev
            };
            y_prev = y;
            format!(",{u:.6},{y:.6}\n")
        })
        .collect();
    let mut w = BufWriter::with_capacity(1 << 20, std::fs::File::create(path).unwrap());
    w.write_all(b"time,u,y\n").unwrap();
    let mut written = 9u64;
    let mut k = 0u64;
    while rows.map_or(written < bytes, |n| k < n) {
        let text = &block[(k % BLOCK) as usize];
        write!(w, "{k}").unwrap();
        w.write_all(text.as_bytes()).unwrap();
        written += text.len() as u64 + k.checked_ilog10().unwrap_or(0) as u64 + 1;
        k += 1;
    }
    w.flush().unwrap();
    let len = std::fs::metadata(path).unwrap().len();
    assert_eq!(len, written);
    (k, len)
}

/// Peak RSS and the like of one `identify mrgia [--trace] --plot` run on a generated file.
struct LargeRun {
    rows: u64,
    bytes: u64,
    peak_kib: u64,
    took: Duration,
    trace_bytes: u64,
}

/// Generate a file (in the target directory: it may be large, and /tmp may be memory) of `rows` rows or
/// `bytes` bytes, run `identify mrgia --json [--trace] --plot` on it, check the results' shape, delete it all.
fn large_file(rows: Option<u64>, bytes: u64, with_trace: bool) -> LargeRun {
    let dir = TempDir::under(Path::new(env!("CARGO_TARGET_TMPDIR")), "large");
    let f = dir.0.join("large.csv");
    let t0 = Instant::now();
    let (rows, bytes) = write_large(&f, rows, bytes);
    let gen_time = t0.elapsed();
    let (trace, plot) = (dir.0.join("trace.csv"), dir.0.join("plot.png"));
    let mut cmd = Command::new(BIN);
    cmd.args(["identify", "mrgia"])
        .arg(&f)
        .args(["--na", "2", "--nb", "0", "--delay", "1", "--json"])
        .arg("--plot")
        .arg(&plot);
    if with_trace {
        cmd.arg("--trace").arg(&trace);
    }
    let (out, peak_kib, took) = run_measured(cmd);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains(&format!("\"samples\":{rows}")), "{text}");
    // The trace ends with the last sample (its time is the row number k, printed as "k.0").
    let mut trace_bytes = 0;
    if with_trace {
        trace_bytes = std::fs::metadata(&trace).unwrap().len();
        let mut tail = std::fs::File::open(&trace).unwrap();
        std::io::Seek::seek(&mut tail, std::io::SeekFrom::End(-4096)).unwrap();
        let mut end = String::new();
        std::io::Read::read_to_string(&mut tail, &mut end).unwrap();
        let last = end.trim_end().rsplit('\n').next().unwrap();
        assert!(
            last.starts_with(&format!("{:?},", (rows - 1) as f64)),
            "{last}"
        );
    }
    assert!(std::fs::read(&plot).unwrap().starts_with(b"\x89PNG"));
    println!(
        "identify mrgia --plot{} on {rows} rows ({:.0} MB, generated in {:.1} s): peak RSS {:.1} MiB, \
         {:.1} s, trace {:.0} MB",
        if with_trace { " --trace" } else { "" },
        bytes as f64 / 1e6,
        gen_time.as_secs_f64(),
        peak_kib as f64 / 1024.0,
        took.as_secs_f64(),
        trace_bytes as f64 / 1e6,
    );
    LargeRun {
        rows,
        bytes,
        peak_kib,
        took,
        trace_bytes,
    }
}

/// The bound on the peak RSS of `identify mrgia` whatever the file's length (measured: about 11 MiB with
/// --trace and --plot, most of it the plot's bitmap and fonts).
const PEAK_RSS_BOUND_MIB: u64 = 64;

#[test]
fn memory_does_not_grow_with_the_file_length() {
    // Ten (release) or twenty (debug) times the rows: a reader that kept the columns would need 24 bytes per
    // row more, i.e. 41 MiB (release) or 9 MiB (debug) more, and one that kept the trajectory far more.
    let (small, large) = if cfg!(debug_assertions) {
        (20_000, 400_000)
    } else {
        (200_000, 2_000_000)
    };
    let a = large_file(Some(small), 0, true);
    let b = large_file(Some(large), 0, true);
    assert_eq!((a.rows, b.rows), (small, large));
    assert!(a.peak_kib > 0 && a.trace_bytes > 0 && b.bytes > 9 * a.bytes);
    let growth_kib = b.peak_kib.saturating_sub(a.peak_kib);
    assert!(
        growth_kib < 4 * 1024,
        "peak RSS {} KiB on {small} rows, {} KiB on {large} rows: it grows with the length",
        a.peak_kib,
        b.peak_kib
    );
    assert!(b.peak_kib < PEAK_RSS_BOUND_MIB * 1024, "{} KiB", b.peak_kib);
    println!(
        "growth of the peak RSS from {small} to {large} rows: {growth_kib} KiB; time ratio {:.1}",
        b.took.as_secs_f64() / a.took.as_secs_f64()
    );
}

#[test]
#[ignore = "a 1 GB file (~37e6 rows, about 10 s): run by scripts/compliance.sh"]
fn one_gigabyte_file_in_bounded_memory() {
    let bytes = std::env::var("BACKLASH_LARGE_BYTES")
        .map(|v| v.parse().expect("BACKLASH_LARGE_BYTES: a number of bytes"))
        .unwrap_or(1_000_000_000);
    // Without --trace: a 1 GB file's trace is 5.6 GB of disk and a minute of writing; the trace's bounded
    // memory is the test above's (2e6 rows with --trace).
    let r = large_file(None, bytes, false);
    assert!(r.bytes >= bytes);
    assert!(
        r.peak_kib < PEAK_RSS_BOUND_MIB * 1024,
        "peak RSS {} KiB exceeds {PEAK_RSS_BOUND_MIB} MiB",
        r.peak_kib
    );
}

/// Run `args` with stdout read for one byte and then closed, as `backlash ... | head -c 1` does; with
/// `stderr_too`, standard error goes into the same pipe (`2>&1 | head -c 1`). Returns the exit code and what
/// reached standard error when it had its own pipe.
fn closed_reader(args: &[&str], stderr_too: bool) -> (Option<i32>, String) {
    use std::io::Read;
    let (mut reader, writer) = std::io::pipe().unwrap();
    let stderr = if stderr_too {
        Stdio::from(writer.try_clone().unwrap())
    } else {
        Stdio::piped()
    };
    let child = Command::new(BIN)
        .args(args)
        .stdout(writer)
        .stderr(stderr)
        .spawn()
        .unwrap();
    let mut one = [0u8; 1];
    let _ = reader.read(&mut one);
    drop(reader);
    let output = child.wait_with_output().unwrap();
    (
        output.status.code(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

#[test]
fn a_closed_reader_is_no_panic_for_any_command() {
    let dir = TempDir::new("closed");
    // Integer counts, 150 samples: the record shape that once hung diagnose.
    let mut csv = String::from("time,u,y\n");
    for k in 0..150 {
        let u = if (k / 25) % 2 == 0 { 1947 } else { 2047 };
        let y = u - 5 + (k * 7 % 11) as i64;
        csv.push_str(&format!("{k},{u},{y}\n"));
    }
    let f = dir.file("counts.csv", csv.as_bytes());
    let f = f.to_str().unwrap();
    // Long enough that `simulate`'s output overflows the pipe's buffer after the reader has gone.
    let mut long = String::from("time,u\n");
    for k in 0..20_000 {
        long.push_str(&format!("{k},{}\n", (k / 25) % 2));
    }
    let long = dir.file("long.csv", long.as_bytes());
    let long = long.to_str().unwrap();
    let runs: Vec<Vec<&str>> = vec![
        vec!["study", "--list-plants"],
        vec!["diagnose", f, "--json"],
        vec!["diagnose", f],
        vec!["identify", "oe", f, "--json"],
        vec![
            "identify", "mrgia", f, "--na", "1", "--nb", "0", "--delay", "1", "--json",
        ],
        vec!["simulate", f],
        vec!["simulate", long],
        vec!["--help"],
    ];
    for args in runs {
        for stderr_too in [false, true] {
            let (code, stderr) = closed_reader(&args, stderr_too);
            // An answer, or a refusal in one line of words (this record does not excite every parameter of
            // every structure): never a panic or a broken pipe's noise.
            // (With standard error closed too, the refusal's line has nowhere to go.)
            let said = (stderr_too && stderr.is_empty())
                || (stderr.starts_with("error: ") && stderr.lines().count() == 1);
            let refused = code == Some(1) && said;
            assert!(
                (code == Some(0) && stderr.is_empty()) || refused,
                "{args:?} (stderr into the pipe too: {stderr_too}): {code:?} {stderr}"
            );
        }
    }
}

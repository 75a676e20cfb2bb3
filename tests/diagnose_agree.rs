//! `backlash diagnose` prints one answer three ways, the text on standard output, the JSON (`--json`) and the
//! report (`--report DIR`), and they agree on every figure they share (issue 56): the verdict on play with
//! its size, standard error and interval, its reasons, the held-out errors before and after each effect, the
//! final model's fit percentage and the error of predicting the mean. Each printed figure must be the JSON's
//! value printed by the one rule of the three (`backlash::report::number`; percentages with one decimal).
//! The record: paper 000's plant with a drifting gap and coloured noise, so that the loop adds a deterministic
//! effect and then a noise model (whose steps print a free-run and a one-step error).

use std::path::{Path, PathBuf};
use std::process::Command;

use backlash::identify::mrgia::paper_input;
use backlash::plant::PlantParams;
use backlash::plant::effects::{ColouredNoise, Effects, GapDrift, simulate_with_effects};
use backlash::report::number;
use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_backlash");

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("backlash-diagnose-agree-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// 1500 samples of the paper's plant under its input, the gap c1 growing by 0.001 a sample, AR(1) noise.
fn record(path: &Path) {
    let n = 1500;
    let u = paper_input(n, 1);
    let params = PlantParams {
        noise_std: 0.05,
        ..PlantParams::PAPER
    };
    let effects = Effects {
        gap_drift: Some(GapDrift {
            c1_rate: 1e-3,
            c2_rate: 0.0,
        }),
        coloured_noise: Some(ColouredNoise { phi: 0.7 }),
        ..Effects::default()
    };
    let out = simulate_with_effects(&params, &effects, &u, 3).unwrap();
    let mut text = String::from("time,u,y\n");
    for (k, (uk, o)) in u.iter().zip(&out).enumerate() {
        text += &format!("{k},{uk:?},{:?}\n", o.y);
    }
    std::fs::write(path, text).unwrap();
}

fn run(args: &[&str]) -> String {
    let out = Command::new(BIN).args(args).output().expect("run backlash");
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("UTF-8")
}

/// The line of `text` that contains `label` (the first).
fn line<'a>(text: &'a str, label: &str) -> &'a str {
    text.lines()
        .find(|l| l.contains(label))
        .unwrap_or_else(|| panic!("no line with '{label}' in:\n{text}"))
}

/// The figure printed right after `label` in `line`: up to a space or one of `),;%*|`.
fn after<'a>(line: &'a str, label: &str) -> &'a str {
    let start = line
        .find(label)
        .unwrap_or_else(|| panic!("no '{label}' in: {line}"))
        + label.len();
    let rest = &line[start..];
    let end = rest
        .find(|c: char| c == ' ' || "),;%*|".contains(c))
        .unwrap_or(rest.len());
    &rest[..end]
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

/// The verdict on play: the text's first line is the report's headline, says the JSON's presence and
/// prints its play, standard error, interval and size in the input's units; the reasons are the JSON's, in
/// order, in both; the report carries the JSON's one-sentence verdict.
fn check_play(text: &str, report: &str, b: &Value) {
    let headline = text.lines().next().unwrap();
    let bold = report
        .split("## Play\n\n**")
        .nth(1)
        .and_then(|r| r.split("**\n").next())
        .expect("the report's play section opens with the headline in bold");
    assert_eq!(headline, bold);
    let presence = b["presence"].as_str().unwrap();
    assert!(
        headline.starts_with(&format!("play: {presence}, ")),
        "{headline}"
    );
    let (play, se) = (f(&b["play"]), b["play_se"].as_f64());
    match presence {
        "absent" => assert_eq!(after(headline, "none above "), number(f(&b["play_bound"]))),
        // A gap of zero or less is said as the fit's gap, never as a play's size.
        _ if play <= 0.0 => {
            assert_eq!(after(headline, "c1 + c2 is "), number(play), "{headline}");
            assert!(headline.contains("which is no play"), "{headline}");
            let se = se.map_or("unknown".into(), number);
            assert_eq!(after(headline, "+/- "), se, "{headline}");
        }
        _ => {
            assert_eq!(after(headline, ", "), number(play), "{headline}");
            assert_eq!(
                after(headline, "+/- "),
                se.map_or("unknown".into(), number),
                "{headline}"
            );
        }
    }
    if let ("present", Some(se)) = (presence, se) {
        assert_eq!(after(headline, "interval "), number(play - 1.96 * se));
        assert_eq!(after(headline, " to "), number(play + 1.96 * se));
        assert_eq!(after(headline, "about "), number(f(&b["play_input_units"])));
    }
    let reasons: Vec<&str> = b["reasons"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_str().unwrap())
        .collect();
    let text_reasons: Vec<&str> = text
        .lines()
        .skip(1)
        .map_while(|l| l.strip_prefix("  - "))
        .collect();
    assert_eq!(text_reasons, reasons);
    let why = report.split("Why:\n\n").nth(1).expect("the reasons");
    let report_reasons: Vec<&str> = why.lines().map_while(|l| l.strip_prefix("- ")).collect();
    assert_eq!(report_reasons, reasons);
    assert!(
        report.contains(b["verdict"].as_str().unwrap()),
        "{}",
        b["verdict"]
    );
}

/// The final model's held-out fit, free-run error and the mean's error: the text's line, the report's line,
/// the JSON's top level and `after`.
fn check_fit(text: &str, report: &str, json: &Value) {
    let fit = format!("{:.1}", f(&json["fit_percent"]));
    assert_eq!(json["fit_percent"], json["after"]["fit_percent"]);
    assert_eq!(json["constant_rmse"], json["after"]["constant_rmse"]);
    let (rmse, constant) = (
        number(f(&json["after"]["rmse"])),
        number(f(&json["constant_rmse"])),
    );
    let t = line(text, "held-out fit of the final model: ");
    assert_eq!(after(t, "held-out fit of the final model: "), fit);
    assert_eq!(after(t, "free-run RMSE "), rmse);
    assert_eq!(after(t, "predicting the fit part's mean: "), constant);
    let r = line(report, "Held-out fit of the final model: ");
    assert_eq!(after(r, "Held-out fit of the final model: **"), fit);
    assert_eq!(after(r, "free-run RMSE "), rmse);
    assert_eq!(after(r, "predicting the fit part's mean gives "), constant);
}

/// Each step of the loop: the text's step line and the report's loop table print the JSON's held-out
/// errors before and after it (free run; one-step prediction for a noise model); the plain model's error is
/// the JSON's `before.rmse`, and the report's result section quotes the first step's.
fn check_steps(text: &str, report: &str, json: &Value) {
    let steps = json["effects"].as_array().unwrap();
    assert!(
        steps.len() >= 2,
        "the record was made for two steps: {}",
        json["effects"]
    );
    let before = number(f(&json["before"]["rmse"]));
    let row0 = line(report, "| 0 | plain model");
    assert_eq!(row0.split(" | ").nth(4), Some(before.as_str()), "{row0}");
    for (i, s) in steps.iter().enumerate() {
        let id = s["id"].as_str().unwrap();
        let (was, now) = (number(f(&s["before_rmse"])), number(f(&s["after_rmse"])));
        let t = line(text, &format!("  step {}: {id} ", i + 1));
        let row = line(report, &format!("| {} | `{id}` |", i + 1));
        let cell = row.split(" | ").nth(4).unwrap();
        assert_eq!(after(cell, ""), now, "{row}");
        let judged = match s["one_step"].as_object() {
            Some(o) => {
                let (b, a) = (number(f(&o["before"])), number(f(&o["after"])));
                assert_eq!(after(t, "one-step prediction RMSE "), b, "{t}");
                assert_eq!(after(t, " -> "), a, "{t}");
                assert_eq!(after(t, "(the free run, "), now, "{t}");
                assert_eq!(after(cell, "(one-step "), b, "{row}");
                assert_eq!(after(cell, " -> "), a, "{row}");
                (b, a)
            }
            None => {
                assert_eq!(after(t, "held-out RMSE "), was, "{t}");
                assert_eq!(after(t, " -> "), now, "{t}");
                (was.clone(), now.clone())
            }
        };
        if i == 0 {
            assert_eq!(was, before);
            let r = line(report, "Pointed to by the test");
            assert_eq!(after(r, "RMSE "), judged.0, "{r}");
            assert_eq!(after(r, "with the plain model, **"), judged.1, "{r}");
        }
    }
    let r = line(report, "**Effects found, in order:");
    assert_eq!(after(r, "Held-out RMSE "), before, "{r}");
    assert_eq!(
        after(r, "with the plain model, **"),
        number(f(&json["after"]["rmse"])),
        "{r}"
    );
}

#[test]
fn text_json_and_report_print_the_same_figures() {
    let file = temp("drift.csv");
    record(&file);
    let dir = temp("report");
    let (file, dir) = (file.to_str().unwrap(), dir.to_str().unwrap());
    let text = run(&["diagnose", file, "--report", dir]);
    let json: Value = serde_json::from_str(&run(&["diagnose", file, "--json"])).expect("JSON");
    let report = std::fs::read_to_string(Path::new(dir).join("report.md")).unwrap();
    check_play(&text, &report, &json["backlash"]);
    check_fit(&text, &report, &json);
    check_steps(&text, &report, &json);
}

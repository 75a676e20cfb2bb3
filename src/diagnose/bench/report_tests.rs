//! The report's tests: each figure's data and caption against the numbers of the diagnosis's JSON, on two
//! test-bench records: one whose disturbance is coloured (a noise model is the last step), one with curved
//! borders (a deterministic effect). No PNG is decoded: the figures are values ([`ReportFigure`]). They live
//! with the bench, whose records they need, so that the report does not import the bench (which imports
//! the report for its own checks).

use serde_json::Value;

use super::{Scenario, scenario};
use crate::diagnose::effects::figure::fmt;
use crate::diagnose::effects::{coloured_noise, curved_borders};
use crate::diagnose::engine::{DiagnoseConfig, Diagnosis, diagnose};
use crate::diagnose::report::figures::{Curves, Names, ReportFigure, figures, rms_between, rms_of};
use crate::diagnose::report::input::{ReportInput, Validation};
use crate::diagnose::search::engine::usable_lags;
use crate::report::plot::{Series, SeriesStyle};

/// Columns with units, as a header `t [s],u [mm],y [kN]` gives them.
const COLUMNS: [&str; 3] = ["t [s]", "u [mm]", "y [kN]"];

struct Case {
    s: Scenario,
    d: Diagnosis,
    t: Vec<f64>,
    json: Value,
}

impl Case {
    fn new(effect: crate::diagnose::effects::EffectId) -> Self {
        let s = scenario(Some(effect), 10_000, 3000);
        let (na, nb, delay) = s.declared;
        let d = diagnose(&s.u, &s.y, &DiagnoseConfig::new(na, nb, delay)).expect("diagnosis runs");
        assert_eq!(d.effect_id(), Some(effect), "the record names its effect");
        let t = (0..s.u.len()).map(|k| k as f64 * 0.01).collect();
        let json = d.to_json(None);
        Self { s, d, t, json }
    }

    fn input<'a>(
        &'a self,
        validations: &'a [Validation],
        warnings: &'a [String],
    ) -> ReportInput<'a> {
        ReportInput {
            file: "bench.csv",
            t: &self.t,
            u: &self.s.u,
            y: &self.s.y,
            decimate: 1,
            rate: None,
            columns: COLUMNS,
            command: None,
            validations,
            warnings,
        }
    }

    fn figures(&self, validations: &[Validation]) -> (Vec<ReportFigure>, Names) {
        let input = self.input(validations, &[]);
        let c = Curves::new(&self.d, &input);
        (figures(&self.d, &input, &c), c.names)
    }

    fn number(&self, path: &[&str]) -> f64 {
        let mut v = &self.json;
        for k in path {
            v = &v[*k];
        }
        v.as_f64().unwrap_or_else(|| panic!("{path:?} in the JSON"))
    }
}

fn figure<'a>(figs: &'a [ReportFigure], file: &str) -> &'a ReportFigure {
    figs.iter().find(|f| f.file == file).expect(file)
}

/// Equal to 1e-8 relative: the figures use the record as given, the JSON's numbers come from its deviations
/// about the operating point, rounded to 2^-30 (about 1e-9) of their scale.
fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-8 * b.abs().max(1e-12)
}

/// The held-out part: the measured trace drawn last (on top), the models dashed; the RMSE between each
/// model's line and the measured one is the JSON's `before.rmse` / `after.rmse`, and the caption prints
/// exactly those numbers. Axes are the columns with their units.
fn check_heldout(case: &Case, names: &Names, figs: &[ReportFigure], extended: bool) {
    let f = figure(figs, "heldout.png");
    let p = &f.panels[0];
    assert_eq!(
        (p.x_label.as_str(), p.y_label.as_str()),
        ("t [s]", "y [kN]")
    );
    let measured = p.series.last().expect("series");
    assert_eq!(measured.label, "measured");
    assert_eq!(measured.style, SeriesStyle::Line);
    let nf = case.d.n_fit;
    assert!(
        measured
            .points
            .iter()
            .map(|q| q.1)
            .eq(case.s.y[nf..case.d.n].iter().copied())
    );
    // First the constant predictor's level: its error is the JSON's `constant_rmse`, in the caption too.
    let constant = &p.series[0];
    assert_eq!(constant.label, "predicting the fit part's mean");
    let c = rms_between(measured, constant);
    assert!(close(c, case.number(&["constant_rmse"])), "{c}");
    assert!(f.caption.contains(&fmt(c)), "{}", f.caption);
    let models = &p.series[1..p.series.len() - 1];
    assert!(models.iter().all(|s| s.style == SeriesStyle::Dashed));
    assert_eq!(models.len(), if extended { 2 } else { 1 });
    let before = rms_between(measured, &models[0]);
    assert!(close(before, case.number(&["before", "rmse"])));
    assert!(f.caption.contains(&fmt(before)), "{}", f.caption);
    assert!(models[0].label.starts_with(&names.plain));
    if extended {
        let after = rms_between(measured, &models[1]);
        assert!(close(after, case.number(&["after", "rmse"])));
        assert!(
            f.caption
                .contains(&format!("{} (blue, RMSE {})", names.after, fmt(after)))
        );
    }
}

/// The residuals: each series' held-out RMS is the JSON's number for it (free run before and after, one-step
/// after with a noise model) and the caption prints it.
fn check_residual(case: &Case, figs: &[ReportFigure], expected: &[(&str, f64)]) {
    let f = figure(figs, "residual.png");
    assert_eq!(f.panels[0].y_label, "residual of y [kN]");
    for (ending, want) in expected {
        let s = f.panels[0]
            .series
            .iter()
            .find(|s| s.label.ends_with(ending))
            .unwrap_or_else(|| {
                panic!(
                    "{ending}: {:?}",
                    f.panels[0]
                        .series
                        .iter()
                        .map(|s| &s.label)
                        .collect::<Vec<_>>()
                )
            });
        let held = Series::line("", s.points[case.d.n_fit..].to_vec());
        assert!(
            close(rms_of(&held), *want),
            "{ending}: {} vs {want}",
            rms_of(&held)
        );
        assert!(
            f.caption.contains(&format!("{} {}", s.label, fmt(*want))),
            "{}",
            f.caption
        );
    }
}

/// The correlations: the plain model's autocorrelation is what the Ljung-Box statistic of the JSON was
/// computed from (Q recomputed from the plotted points), and the caption's lag-1 values are the plotted ones.
fn check_correlations(case: &Case, figs: &[ReportFigure]) {
    let f = figure(figs, "correlations.png");
    let acf = &f.panels[0].series[0];
    let n = case.d.n_fit as f64;
    assert_eq!(
        acf.points.len(),
        usable_lags(case.d.config.lags, case.d.n_fit)
    );
    let q: f64 = n * (n + 2.0) * acf.points.iter().map(|(l, r)| r * r / (n - l)).sum::<f64>();
    let lb = case.json["tests"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["name"] == "ljung-box")
        .unwrap();
    assert!(close(q, lb["statistic"].as_f64().unwrap()), "{q} vs {lb}");
    for s in f.panels[0]
        .series
        .iter()
        .filter(|s| s.style == SeriesStyle::Points)
    {
        assert!(
            f.caption
                .contains(&format!("{} {}", s.label, fmt(s.points[0].1))),
            "{}",
            f.caption
        );
        assert!(s.points.iter().all(|p| p.0.fract() == 0.0));
    }
}

/// The steps: whole-number x; the free-run line is the JSON's `before.rmse` then each step's `after_rmse`; a
/// noise model's one-step line ends at `after.one_step`; the linear reference is `linear.rmse`; the caption
/// prints each.
fn check_steps(case: &Case, figs: &[ReportFigure]) {
    let f = figure(figs, "steps.png");
    let free = &f.panels[0].series[0];
    let mut want = vec![case.number(&["before", "rmse"])];
    for step in case.json["effects"].as_array().unwrap() {
        want.push(step["after_rmse"].as_f64().unwrap());
    }
    assert_eq!(free.points.len(), want.len());
    for (i, (p, w)) in free.points.iter().zip(&want).enumerate() {
        assert_eq!(p.0, i as f64);
        assert!(close(p.1, *w));
        assert!(
            f.caption.contains(&format!("step {i}: {}", fmt(*w))),
            "{}",
            f.caption
        );
    }
    let one_step = f.series(0, "held-out one-step prediction RMSE");
    match case.json["after"].get("one_step") {
        Some(o) => {
            let p = &one_step.expect("a one-step line").points;
            assert!(close(p[p.len() - 1].1, o["after"].as_f64().unwrap()));
            assert!(close(p[p.len() - 2].1, o["before"].as_f64().unwrap()));
            assert!(f.caption.contains(&fmt(o["after"].as_f64().unwrap())));
        }
        None => assert!(one_step.is_none()),
    }
    let linear = f.series(0, "best linear model, free run").unwrap();
    assert!(
        linear
            .points
            .iter()
            .all(|p| close(p.1, case.number(&["linear", "rmse"])))
    );
    assert_eq!(f.panels[0].y_label, "held-out RMSE of y [kN]");
}

/// A validation on the record itself: the RMSEs between the plotted lines are the validation's numbers.
fn check_validation(case: &Case) {
    let result = case.d.cross_validate(&case.s.u, &case.s.y).unwrap();
    let v = [Validation {
        name: "itself".into(),
        t: case.t.clone(),
        y: case.s.y.clone(),
        result,
    }];
    let (figs, names) = case.figures(&v);
    let f = figure(&figs, "validate_itself.png");
    let p = &f.panels[0];
    let measured = p.series.last().unwrap();
    let models = &p.series[..p.series.len() - 1];
    let wanted = [v[0].result.rmse_before, v[0].result.rmse_after];
    assert_eq!(
        models.len(),
        if v[0].result.before == v[0].result.after {
            1
        } else {
            2
        }
    );
    for (s, want) in models.iter().zip(wanted) {
        assert!(close(rms_between(measured, s), want));
        assert!(f.caption.contains(&format!(
            "{} ({}",
            s.label,
            if s.color == 3 { "red" } else { "blue" }
        )));
        assert!(f.caption.contains(&fmt(want)));
    }
    assert!(f.caption.contains(&names.plain));
}

/// A coloured disturbance: the noise model leaves the simulation as it is, so the plain model's free run is
/// drawn once (named for both), and the one-step prediction's residual is drawn and labelled as such.
#[test]
fn figures_of_a_noise_model_match_the_json() {
    let case = Case::new(coloured_noise::ID);
    let (figs, names) = case.figures(&[]);
    assert_eq!(names.plain, "plain model (declared structure)");
    assert_eq!(names.after, "plain + coloured-noise, free run");
    let one_step = names.one_step.clone().expect("a noise model");
    check_heldout(&case, &names, &figs, false);
    check_residual(
        &case,
        &figs,
        &[
            ("y - simulation", case.number(&["before", "rmse"])),
            (
                "y - prediction",
                case.number(&["after", "one_step", "after"]),
            ),
        ],
    );
    let f = figure(&figs, "correlations.png");
    let pred = f.series(0, &format!("{one_step}: y - prediction")).unwrap();
    let plain = &f.panels[0].series[0];
    assert!(pred.points[0].1.abs() < plain.points[0].1.abs());
    check_correlations(&case, &figs);
    check_steps(&case, &figs);
    check_validation(&case);
}

/// Curved borders: a deterministic effect, its own free run drawn beside the plain model's.
#[test]
fn figures_of_a_deterministic_effect_match_the_json() {
    let case = Case::new(curved_borders::ID);
    let (figs, names) = case.figures(&[]);
    assert!(names.one_step.is_none());
    assert!(names.after.starts_with("plain + curved-borders"));
    check_heldout(&case, &names, &figs, true);
    let after = case.number(&["after", "rmse"]);
    check_residual(
        &case,
        &figs,
        &[
            (
                &format!("{}: y - simulation", names.plain),
                case.number(&["before", "rmse"]),
            ),
            (&format!("{}: y - simulation", names.after), after),
        ],
    );
    check_correlations(&case, &figs);
    check_steps(&case, &figs);
}

/// The report: the structure's word (declared, or chosen when the tool chose it), the warnings shown, every
/// figure written, the evidence caption from the same numbers as the correlations figure.
#[test]
fn the_report_says_declared_or_chosen_and_shows_the_warnings() {
    let mut case = Case::new(coloured_noise::ID);
    let warnings =
        vec!["the input never reverses: nothing can be said about the backlash".to_string()];
    let dir = std::env::temp_dir().join(format!("backlash-report-words-{}", std::process::id()));
    let md =
        crate::diagnose::report::write_report(&dir, &case.d, &case.input(&[], &warnings)).unwrap();
    let text = std::fs::read_to_string(md).unwrap();
    assert!(
        text.contains(&format!("## Warnings\n\n- **{}**", warnings[0])),
        "{text}"
    );
    assert!(text.contains("declared by the user"));
    assert!(!text.contains("declared model"));
    for f in ["heldout", "residual", "correlations", "evidence", "steps"] {
        assert!(
            dir.join(format!("{f}.png")).metadata().unwrap().len() > 1000,
            "{f}"
        );
    }
    let (figs, names) = case.figures(&[]);
    let pred = figure(&figs, "correlations.png")
        .series(0, &format!("{}: y - prediction", names.one_step.unwrap()))
        .unwrap()
        .points[0]
        .1;
    assert!(
        text.contains(&format!("blue; lag 1: {}", fmt(pred))),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
    case.d.structure.chosen_by = "selected";
    let names = Names::of(&case.d);
    assert_eq!(names.plain, "plain model (chosen structure)");
}

//! The diagnosis report for a test engineer: `report.md` and PNG figures in one folder.
//!
//! The model before any effect is the *plain model*, of the structure the user declared or the tool chose
//! (the report says which); the final model is named by the effects it adds.
//!
//! Figures (all against the record's time unless said; each figure's data and caption are one value,
//! [`ReportFigure`], but the evidence figure, which the chosen effect draws):
//! - `heldout.png`: the held-out part, the measured output on top of the plain and the final model (dashed);
//! - `residual.png`: the residuals over the whole record (free run; with a noise model also its one-step
//!   prediction's), the fit / held-out split marked;
//! - `correlations.png`: autocorrelation and residual-input cross-correlation of those residuals on the fit
//!   part, with the 95% bands of a white residual;
//! - `evidence.png`: the evidence for the first effect (what the pointing test saw and what the fit made
//!   of it); for `null`, the measured output against the input with the plain model;
//! - `steps.png`: the held-out error after each step of the loop, free run and (for a noise model) one-step;
//! - `validate_<name>.png`: for each cross-record validation, measured against both models.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::diagnose::effects::CATALOGUE;
use crate::diagnose::effects::figure::fmt;
use crate::diagnose::report::figures::{Curves, Names, ReportFigure, evidence, figures};
use crate::diagnose::report::input::{ReportError, ReportInput};
use crate::diagnose::report::play::play_figure;
use crate::diagnose::search::decision::DECISION_RULE;
use crate::diagnose::search::engine::Diagnosis;
use crate::io::write_atomic;

/// Write `report.md` and the figures into `dir` (created if needed). Returns the Markdown file's path.
pub fn write_report(
    dir: &Path,
    d: &Diagnosis,
    input: &ReportInput,
) -> Result<PathBuf, ReportError> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Folder {
        path: dir.to_path_buf(),
        source,
    })?;
    let c = Curves::new(d, input);
    let mut drawn: Vec<ReportFigure> = vec![play_figure(d, input)];
    drawn.extend(figures(d, input, &c));
    for f in &drawn {
        f.draw(dir)?;
    }
    let mut listed: Vec<(String, String)> =
        drawn.into_iter().map(|f| (f.file, f.caption)).collect();
    let at = listed.len().min(4);
    listed.insert(at, ("evidence.png".into(), evidence(dir, d, input, &c)?));
    let md = markdown(d, input, &listed);
    let path = dir.join("report.md");
    write_atomic(&path, |w| w.write_all(md.as_bytes())).map_err(|source| ReportError::Write {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

/// The effects that search several structures with their BIC penalties ("extra-delay 1.10, ...").
fn structure_penalties() -> String {
    CATALOGUE
        .iter()
        .filter(|e| e.structure_penalty() > 0.0)
        .map(|e| format!("{} {:.2}", e.id(), e.structure_penalty()))
        .collect::<Vec<_>>()
        .join(", ")
}

fn list(v: &[f64]) -> String {
    v.iter().map(|x| fmt(*x)).collect::<Vec<_>>().join(", ")
}

/// An effect's parameters (the JSON object of [`Diagnosis::to_json`]) as `name value, ...`.
fn params_text(params: &serde_json::Value) -> String {
    params
        .as_object()
        .map(|o| {
            o.iter()
                .filter(|(k, _)| !k.ends_with("unit") && *k != "note")
                .map(
                    |(k, v)| match (v.as_i64(), v.as_f64(), v.as_array(), v.as_str()) {
                        (Some(i), _, _, _) => format!("{k} {i}"),
                        (_, Some(x), _, _) => format!("{k} {}", fmt(x)),
                        (_, _, Some(a), _) => format!(
                            "{k} [{}]",
                            a.iter()
                                .map(|x| x.as_f64().map_or(x.to_string(), fmt))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                        (_, _, _, Some(t)) => format!("{k} {t}"),
                        _ => format!("{k} {v}"),
                    },
                )
                .collect::<Vec<_>>()
                .join(", ")
        })
        .unwrap_or_default()
}

/// The loop's steps as a table (effect, the test that pointed to it, fit and held-out errors, BIC) and what
/// each later round tried.
fn loop_section(s: &mut String, d: &Diagnosis) {
    let steps = d.steps();
    if steps.is_empty() {
        return;
    }
    let _ = writeln!(s, "## The loop\n");
    let _ = writeln!(
        s,
        "After an effect is kept, the extended model is the current one: its residual is tested again and the \
         candidates it points to are fitted on top of it (all parameters jointly, so the last step is the \
         joint refit of every effect found). Stopped: {}.\n",
        d.stopped
    );
    let _ = writeln!(
        s,
        "| step | effect | pointed to by | fit RMSE | held-out RMSE | BIC | dBIC |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- | --- |");
    let _ = writeln!(
        s,
        "| 0 | {} | - | {} | {} | {:.1} | - |",
        Names::of(d).plain,
        fmt(d.base_fit_rmse),
        fmt(d.base_heldout_rmse),
        d.base_bic
    );
    for (i, c) in steps.iter().enumerate() {
        let _ = writeln!(
            s,
            "| {} | `{}` | {} | {} | {}{} | {:.1} | {:+.1} |",
            i + 1,
            c.id,
            c.pointed_by.first().copied().unwrap_or("-"),
            fmt(c.fit_rmse),
            fmt(c.heldout_rmse),
            c.one_step.map_or(String::new(), |o| format!(
                " (one-step {} -> {})",
                fmt(o.before),
                fmt(o.after)
            )),
            c.bic,
            c.delta_bic
        );
    }
    for (i, r) in d.later.iter().enumerate() {
        let tried: Vec<String> = r
            .found
            .candidates
            .iter()
            .map(|c| {
                format!(
                    "`{}` {} ({})",
                    c.id,
                    if c.supported {
                        "supported"
                    } else {
                        "not supported"
                    },
                    c.reason
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "\nRound {}: {}.",
            i + 2,
            if tried.is_empty() {
                "no residual test pointed to an effect that can still be added".to_string()
            } else {
                tried.join("; ")
            }
        );
    }
    let _ = writeln!(s);
}

fn markdown(d: &Diagnosis, input: &ReportInput, figures: &[(String, String)]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Diagnosis of {}\n", input.file);
    section_verdict(&mut s, d, figures);
    section_warnings(&mut s, input);
    section_header(&mut s, d, input);
    section_structure(&mut s, d);
    section_backlash(&mut s, d);
    section_result(&mut s, d);
    section_effect_paragraph(&mut s, d);
    section_loop_and_rule(&mut s, d);
    section_tests(&mut s, d);
    section_candidates(&mut s, d);
    section_models(&mut s, d);
    section_validations(&mut s, d, input);
    section_figures(&mut s, d, figures);
    s
}

/// The title, the command, the model and the split of the record.
fn section_header(s: &mut String, d: &Diagnosis, input: &ReportInput) {
    let st = &d.structure;
    let _ = writeln!(s, "## The record and the model\n");
    if let Some(c) = &input.command {
        let _ = writeln!(s, "Produced by `{c}`.\n");
    }
    let _ = writeln!(
        s,
        "Model: pseudo-Wiener with backlash, {} ({}; m1 = 1 is the normalisation); without any effect it is \
         called the plain model below. Record: {} samples \
         after decimation by {}; the first {} (about {:.0}%) fit the models, the last {} are held out and only \
         used to judge them (the models are simulated over the whole record, so the held-out part starts from \
         the right state). Every held-out error below is this free-run simulation error. Initial state: {}.\n",
        st.chosen,
        match Names::structure_word(d) {
            "declared" => "declared by the user",
            _ => "chosen from the data",
        },
        d.n,
        input.decimate.max(1),
        d.n_fit,
        100.0 * d.n_fit as f64 / d.n as f64,
        d.n - d.n_fit,
        d.initial.reason
    );
    if let Some(r) = &input.rate {
        let _ = writeln!(s, "Sampling rate: {r}.\n");
    }
    if let Some(c) = d.closest_alternative() {
        let _ = writeln!(
            s,
            "Closest alternative: `{}` was rejected ({}) although its held-out error, {}, is below the chosen model's, {}.\n",
            c.id.as_str(),
            c.reason,
            fmt(c.heldout_rmse),
            fmt(c.chosen_heldout_rmse)
        );
    }
}

/// The verdict on play and its reasons, the figure that shows the play, and how much the final model explains
/// against a constant: the report's first page.
fn section_verdict(s: &mut String, d: &Diagnosis, figures: &[(String, String)]) {
    let b = &d.backlash;
    let _ = writeln!(s, "## Play\n\n**{}**\n", b.headline());
    let _ = writeln!(s, "Why:\n");
    for r in &b.reasons {
        let _ = writeln!(s, "- {r}");
    }
    if let Some(e) = &b.experiment {
        let _ = writeln!(s, "\nThe experiment that would decide: {e}.");
    }
    if let Some((file, caption)) = figures.iter().find(|(f, _)| f == "play.png") {
        let _ = writeln!(s, "\n![The play]({file})\n\n*{caption}*\n");
    }
    let _ = writeln!(
        s,
        "Held-out fit of the final model: **{:.1}%** (free-run RMSE {}; predicting the fit part's mean gives \
         {}). The fits worked about the operating point u = {}, y = {} (the fit part's mean input, the first output).\n",
        d.explained.fit_percent,
        fmt(d.after_rmse()),
        fmt(d.explained.constant_rmse),
        fmt(d.operating_point.u),
        fmt(d.operating_point.y)
    );
}

/// The record's warnings (the JSON's `warnings`): what the record cannot support.
fn section_warnings(s: &mut String, input: &ReportInput) {
    if input.warnings.is_empty() {
        return;
    }
    let _ = writeln!(s, "## Warnings\n");
    for w in input.warnings {
        let _ = writeln!(s, "- **{w}**");
    }
    let _ = writeln!(s);
}

/// How the structure was chosen, when it was not declared.
fn section_structure(s: &mut String, d: &Diagnosis) {
    let st = &d.structure;
    if !st.candidates.is_empty() {
        let _ = writeln!(s, "## Structure\n");
        let _ = writeln!(
            s,
            "Chosen on the fit part only ({} samples estimate, the next {} validate): {}.\n\nCriterion: {}.\n",
            st.estimation_samples, st.validation_samples, st.reason, st.criterion
        );
        let _ = writeln!(
            s,
            "| na | nb | delay | linear output-error model, validation RMSE | backlash model, validation RMSE | chosen |"
        );
        let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
        let opt = |v: Option<f64>| v.map_or("-".to_string(), fmt);
        for c in st.candidates.iter().take(12) {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} |",
                c.structure.na,
                c.structure.nb,
                c.structure.delay,
                opt(c.linear_rmse),
                opt(c.model_rmse),
                if c.chosen { "**yes**" } else { "" }
            );
        }
        let _ = writeln!(
            s,
            "\n({} structures compared in all; the table shows those fitted fully, then the best of the rest.)\n",
            st.candidates.len()
        );
    }
}

/// Whether the data support the backlash rather than a straight line.
fn section_backlash(s: &mut String, d: &Diagnosis) {
    let _ = writeln!(s, "## Backlash or a straight line?\n");
    let _ = writeln!(
        s,
        "{}.\n\nThe best linear output-error model of the same structure (the backlash with c1 = -c2, m2 = 1) has \
         held-out RMSE {} (fit part {}); the backlash model {} (fit part {}). The backlash fit starts from the \
         linear model among others, so its fit-part error is never above it.\n",
        d.backlash.verdict,
        fmt(d.linear.heldout_rmse),
        fmt(d.linear.fit_rmse),
        fmt(d.base_heldout_rmse),
        fmt(d.base_fit_rmse)
    );
}

/// The effects found, in order, when there are several.
fn section_result(s: &mut String, d: &Diagnosis) {
    let _ = writeln!(s, "## Result\n");
    let steps = d.steps();
    if steps.len() > 1 {
        let names: Vec<String> = steps.iter().map(|c| format!("`{}`", c.id)).collect();
        let _ = writeln!(
            s,
            "**Effects found, in order: {}.** Held-out RMSE {} with the plain model, **{}** with all of them \
             (steps in the section *The loop*). The first:\n",
            names.join(", then "),
            fmt(d.base_heldout_rmse),
            fmt(d.after_rmse())
        );
    }
}

/// The first effect (or null) with its evidence in numbers.
fn section_effect_paragraph(s: &mut String, d: &Diagnosis) {
    let effect = d.effect();
    match effect {
        Some(c) => {
            // The errors the effect was judged by: one-step prediction for a noise model, else free run.
            let judged = c
                .one_step
                .map_or((d.base_heldout_rmse, c.heldout_rmse), |o| {
                    (o.before, o.after)
                });
            let _ = writeln!(
                s,
                "**Effect: `{}`** — {}.\n\nPointed to by the test *{}*. Held-out {} RMSE {} with the plain model, \
                 **{}** with the extension ({:.1}x lower; Diebold-Mariano z = {:.1}); BIC on the fit part {} lower.\n",
                c.id,
                c.id.describe(),
                d.pointing_test().unwrap_or("-"),
                c.error_kind,
                fmt(judged.0),
                fmt(judged.1),
                judged.0 / judged.1.max(f64::MIN_POSITIVE),
                c.heldout_z,
                fmt(-c.delta_bic)
            );
            if let Some(o) = c.one_step {
                let _ = writeln!(
                    s,
                    "A noise model is judged by one-step-ahead prediction, y(k) - [s(k) + sum phi_i (y(k-i) - s(k-i))] \
                     with s the simulated output: held-out one-step error {} before (the plain model's predictor \
                     is its simulation) and {} after. Its free-run simulation error, which every other held-out \
                     error of this report is, goes from {} to {}.\n",
                    fmt(o.before),
                    fmt(o.after),
                    fmt(d.base_heldout_rmse),
                    fmt(c.heldout_rmse)
                );
            }
        }
        None => {
            let _ = writeln!(
                s,
                "**Effect: null** — no extension of the catalogue is supported by the evidence. Held-out RMSE of the \
                 plain model: {}.\n",
                fmt(d.base_heldout_rmse)
            );
        }
    }
}

/// The loop, the decision rule, what was set aside and what was not tried.
fn section_loop_and_rule(s: &mut String, d: &Diagnosis) {
    loop_section(s, d);
    let _ = writeln!(s, "Decision rule: {}.\n", DECISION_RULE);
    for why in &d.set_aside {
        let _ = writeln!(s, "Set aside: {why}.\n");
    }
    if !d.not_tried.is_empty() {
        let names: Vec<String> = d.not_tried.iter().map(|e| format!("`{e}`")).collect();
        let _ = writeln!(
            s,
            "**Not tried** (the time budget of {:.0} s was spent first): {}.\n",
            d.config.time_budget.as_secs_f64(),
            names.join(", ")
        );
    }
}

/// The residual tests on the plain model.
fn section_tests(s: &mut String, d: &Diagnosis) {
    let _ = writeln!(s, "## Residual tests\n");
    let _ = writeln!(
        s,
        "On the fit part of the plain model's residual (samples 0..{}). A test that rejects points to the \
         effects listed; those effects are fitted as candidates.\n",
        d.n_fit
    );
    let _ = writeln!(
        s,
        "| test | statistic | threshold | rejects | points to | detail |"
    );
    let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- |");
    for t in &d.tests {
        let to: Vec<String> = t.points_to.iter().map(|e| format!("`{e}`")).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            t.verdict.name,
            fmt(t.verdict.statistic),
            fmt(t.verdict.threshold),
            if t.verdict.rejects { "**yes**" } else { "no" },
            to.join(", "),
            t.verdict.detail.replace('|', "/")
        );
    }
}

/// The candidates of the first round with their parameters and judgements.
fn section_candidates(s: &mut String, d: &Diagnosis) {
    let _ = writeln!(s, "\n## Candidates\n");
    if d.candidates.is_empty() {
        let _ = writeln!(s, "No test rejected: no candidate was fitted.\n");
    } else {
        let _ = writeln!(
            s,
            "Each candidate extension is fitted on the fit part (Levenberg-Marquardt on the simulated output, \
             started from the plain model's fit). BIC = N ln(RSS/N) + k ln N (+ ln of the number of structures \
             searched: {}); dBIC < 0 favours the extension.\n",
            structure_penalties()
        );
        let _ = writeln!(
            s,
            "| effect | pointed by | parameters | fit RMSE | held-out RMSE | z | dBIC | supported | why |"
        );
        let _ = writeln!(s, "| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
        let json = d.to_json(None);
        for (i, c) in d.candidates.iter().enumerate() {
            let p = params_text(&json["candidates"][i]["parameters"]);
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {:.1} | {:+.1} | {} | {} |",
                if Some(i) == d.chosen {
                    format!("**`{}`** (chosen)", c.id)
                } else {
                    format!("`{}`", c.id)
                },
                c.pointed_by.join(", "),
                p,
                fmt(c.fit_rmse),
                fmt(c.heldout_rmse),
                c.heldout_z,
                c.delta_bic,
                if c.supported { "yes" } else { "no" },
                c.reason
            );
        }
        let _ = writeln!(s);
    }
}

/// The plain and the extended model's parameters.
fn section_models(s: &mut String, d: &Diagnosis) {
    let effect = d.effect();
    let _ = writeln!(s, "## Models\n");
    let b = &d.base.base;
    let _ = writeln!(
        s,
        "Plain model ({} structure) fitted: a = [{}], b = [{}], m1 = 1, m2 = {}, c1 = {}, c2 = {}; fit RMSE {}, held-out RMSE {}.\n",
        Names::structure_word(d),
        list(&b.a),
        list(&b.b),
        fmt(b.m2),
        fmt(b.c1),
        fmt(b.c2),
        fmt(d.base_fit_rmse),
        fmt(d.base_heldout_rmse)
    );
    if let Some(c) = effect {
        let b = &c.model.base;
        let _ = writeln!(
            s,
            "Extended model ({}): na = {}, nb = {}, delay = {}, a = [{}], b = [{}], m1 = 1, m2 = {}, c1 = {}, c2 = {}; {}: {}.\n",
            c.id,
            b.na,
            b.nb,
            b.delay,
            list(&b.a),
            list(&b.b),
            fmt(b.m2),
            fmt(b.c1),
            fmt(b.c2),
            c.id,
            params_text(&d.to_json(None)["effect"]["parameters"])
        );
    }
}

/// The cross-record validations.
fn section_validations(s: &mut String, d: &Diagnosis, input: &ReportInput) {
    let effect = d.effect();
    if !input.validations.is_empty() {
        let _ = writeln!(s, "## Cross-record validation\n");
        let _ = writeln!(
            s,
            "The models fitted above, simulated over other records from rest (no refit).\n\n| record | samples | output std | RMSE plain model | RMSE {} |\n| --- | --- | --- | --- | --- |",
            effect.map_or("chosen (null)".to_string(), |c| c.id.to_string())
        );
        for v in input.validations {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                v.name,
                v.result.samples,
                fmt(v.result.y_std),
                fmt(v.result.rmse_before),
                fmt(v.result.rmse_after)
            );
        }
        let _ = writeln!(s);
    }
}

/// The figures with their captions, and why no offset effect.
fn section_figures(s: &mut String, _d: &Diagnosis, figures: &[(String, String)]) {
    let _ = writeln!(s, "## Figures\n");
    for (f, cap) in figures.iter().filter(|(f, _)| f != "play.png") {
        let _ = writeln!(s, "![{f}]({f})\n\n{cap}\n");
    }
    let _ = writeln!(
        s,
        "## Why no \"offset\" effect\n\nA constant offset is not an effect: every fit works about the operating \
         point (the fit part's means of u and y), so a record shifted by constants, as a sensor's arbitrary zero \
         shifts it, gets the same answer; the models' parameters are deviations from that point."
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The parameters in words, in the JSON object's (sorted) key order: integers as they are, numbers with
    /// four decimals or in exponent form below 1e-3, lists element by element, text as it is; units and
    /// notes left out; anything else (here a flag) as JSON.
    #[test]
    fn parameters_in_words() {
        let p = serde_json::json!({
            "delay": 3,
            "c1_rate": 0.00002,
            "rate_unit": "per sample",
            "note": "a remark",
            "phi": [0.5, -0.25, "x"],
            "form": "Series",
            "flag": true,
        });
        assert_eq!(
            params_text(&p),
            "c1_rate 2.000e-5, delay 3, flag true, form Series, phi [0.5000, -0.2500, \"x\"]"
        );
        assert_eq!(params_text(&serde_json::json!(null)), "");
        assert_eq!(params_text(&serde_json::json!({})), "");
    }
}

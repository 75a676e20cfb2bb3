//! Monte Carlo study of the paper 000, section 4 example: MRGIA (paper and recommended settings), the
//! output-error fit started from MRGIA, and the Cramer-Rao bound, against the record length N.
//!
//! For each seed s: the input is [`paper_input`]`(max N, s)`, the plant [`PlantParams::PAPER`], the noise
//! white Gaussian with standard deviation `std(w) / snr` (w the noise-free output over the longest record:
//! the paper's "SNR 43" is the square root of the ratio of the output and noise variances) from seed
//! `s + 0x5EED_0000_0000`. Every record of length N is the first N samples of that run. MRGIA runs once per
//! setting and is read at each N; the OE fit runs on each prefix from the MRGIA estimates at that N (the
//! same starts as [`super::fit`]); the CRB is computed for each prefix at the truth with the true noise std.

use super::{OeConfig, OeFit, crb, fit_from, param_names, theta_of};
use crate::identify::mrgia::{Estimate, Mrgia, MrgiaConfig, paper_input};
use crate::plant::{Plant, PlantParams};
use crate::report::plot::{Panel, PlotError, Series, grid_plot};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Same offset as `mrgia::paper_study_with`: independent ChaCha8 streams for input and noise.
const NOISE_SEED_OFFSET: u64 = 0x5EED_0000_0000;

/// What to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyConfig {
    /// Number of Monte Carlo runs (seeds `first_seed .. first_seed + seeds`).
    pub seeds: u64,
    pub first_seed: u64,
    /// Record lengths.
    pub ns: Vec<usize>,
    /// Signal-to-noise ratio std(w) / noise std; paper: 43.
    pub snr: f64,
}

impl StudyConfig {
    /// The paper's noisy example (SNR 43) at N = 300, 1000, 3000, 10000.
    pub fn paper(seeds: u64) -> Self {
        Self {
            seeds,
            first_seed: 0,
            ns: vec![300, 1000, 3000, 10000],
            snr: 43.0,
        }
    }
}

/// Statistics of one method at one N over the runs, per parameter in theta order (a1, a2, b0, m2, c1, c2).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodStats {
    /// `mrgia-paper`, `mrgia-recommended`, `oe` or `crb`.
    pub method: String,
    pub n: usize,
    /// Root mean square error over the runs; for `crb` the root mean CRB variance (the RMSE an efficient
    /// unbiased estimator would have on these inputs).
    pub rmse: Vec<f64>,
    /// Mean error (0 for `crb`).
    pub bias: Vec<f64>,
    /// Median over runs of the largest relative error (for `crb`: of the largest relative CRB std).
    pub median_max_rel: f64,
    /// `oe` only: fraction of runs whose interval estimate +/- 1.96 std_err covers the truth.
    pub coverage: Option<Vec<f64>>,
    /// `oe` only: root mean square of the reported standard errors.
    pub rms_std_err: Option<Vec<f64>>,
    /// Runs whose method failed (excluded from the statistics).
    pub failures: usize,
    /// Runs included.
    pub runs: usize,
}

/// Everything the study measured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyResult {
    pub config: StudyConfig,
    pub names: Vec<String>,
    pub truth: Vec<f64>,
    pub stats: Vec<MethodStats>,
}

/// The method names, in plotting order.
pub const METHODS: [&str; 4] = ["mrgia-paper", "mrgia-recommended", "oe", "crb"];

/// Accumulates per-run errors of one method at one N.
#[derive(Default)]
struct Acc {
    err: Vec<Vec<f64>>,
    max_rel: Vec<f64>,
    covered: Vec<Vec<bool>>,
    std_err: Vec<Vec<f64>>,
    failures: usize,
}

impl Acc {
    fn push(&mut self, est: &[f64], truth: &[f64]) {
        let e: Vec<f64> = est.iter().zip(truth).map(|(e, t)| e - t).collect();
        self.max_rel.push(
            e.iter()
                .zip(truth)
                .map(|(e, t)| (e / t).abs())
                .fold(0.0, f64::max),
        );
        self.err.push(e);
    }

    fn stats(&self, method: &str, n: usize, p: usize) -> MethodStats {
        let runs = self.err.len();
        let mean = |f: &dyn Fn(&Vec<f64>, usize) -> f64| -> Vec<f64> {
            (0..p)
                .map(|i| {
                    if runs == 0 {
                        f64::NAN
                    } else {
                        self.err.iter().map(|e| f(e, i)).sum::<f64>() / runs as f64
                    }
                })
                .collect()
        };
        let rmse = mean(&|e, i| e[i] * e[i]).iter().map(|v| v.sqrt()).collect();
        let bias = if method == "crb" {
            vec![0.0; p]
        } else {
            mean(&|e, i| e[i])
        };
        let coverage = (!self.covered.is_empty()).then(|| {
            (0..p)
                .map(|i| {
                    self.covered.iter().filter(|c| c[i]).count() as f64 / self.covered.len() as f64
                })
                .collect()
        });
        let rms_std_err = (!self.std_err.is_empty()).then(|| {
            (0..p)
                .map(|i| {
                    (self.std_err.iter().map(|s| s[i] * s[i]).sum::<f64>()
                        / self.std_err.len() as f64)
                        .sqrt()
                })
                .collect()
        });
        MethodStats {
            method: method.to_string(),
            n,
            rmse,
            bias,
            median_max_rel: median(&self.max_rel),
            coverage,
            rms_std_err,
            failures: self.failures,
            runs,
        }
    }
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let m = s.len() / 2;
    if s.len().is_multiple_of(2) {
        0.5 * (s[m - 1] + s[m])
    } else {
        s[m]
    }
}

fn std_dev(v: &[f64]) -> f64 {
    let n = v.len().max(1) as f64;
    let mean = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// The starts of [`super::fit`] from the two MRGIA estimates.
pub(super) fn default_starts(
    rec: Estimate,
    paper: Option<Estimate>,
) -> Vec<(&'static str, Estimate)> {
    let mut starts = vec![("mrgia-recommended", rec.clone())];
    if let Some(paper) = paper {
        starts.push(("mrgia-paper", paper));
        let mut half = rec;
        half.c1 *= 0.5;
        half.c2 *= 0.5;
        starts.push(("mrgia-recommended-half-gaps", half));
    }
    starts
}

/// One run of the study: the record of seed `s`, truncated at each N, and the fits. Returns, per N, the
/// estimates of the two MRGIA settings, the OE fit (or its error) and the CRB variances.
type RunResult = Vec<(Vec<f64>, Vec<f64>, Option<OeFit>, Option<Vec<f64>>)>;

fn one_run(cfg: &StudyConfig, s: u64) -> RunResult {
    let truth = PlantParams::PAPER;
    let (na, nb, d) = (truth.arx.na, truth.arx.nb, truth.arx.delay);
    let n_max = cfg.ns.iter().copied().max().unwrap_or(0);
    let u = paper_input(n_max, s);
    let clean = Plant::simulate(truth, &u).expect("the paper plant is valid");
    let w: Vec<f64> = clean.iter().map(|o| o.w).collect();
    let noise_std = std_dev(&w) / cfg.snr;
    let mut p = truth;
    p.noise_std = noise_std;
    p.noise_seed = s.wrapping_add(NOISE_SEED_OFFSET);
    let y: Vec<f64> = Plant::simulate(p, &u)
        .expect("noise std is finite")
        .iter()
        .map(|o| o.y)
        .collect();
    let mut paper = Mrgia::new(MrgiaConfig::paper(na, nb, d)).expect("valid");
    let mut rec = Mrgia::new(MrgiaConfig::recommended(na, nb, d)).expect("valid");
    let mut order: Vec<usize> = (0..cfg.ns.len()).collect();
    order.sort_by_key(|&i| cfg.ns[i]);
    let mut out: RunResult = vec![(vec![], vec![], None, None); cfg.ns.len()];
    let mut done = 0;
    let oe_cfg = OeConfig::new(na, nb, d);
    for &i in &order {
        let n = cfg.ns[i];
        while done < n {
            paper.update(u[done], y[done]);
            rec.update(u[done], y[done]);
            done += 1;
        }
        let (ep, er) = (paper.estimate(), rec.estimate());
        let starts = default_starts(er.clone(), Some(ep.clone()));
        let oe = fit_from(&oe_cfg, &u[..n], &y[..n], &starts).ok();
        let bound = crb(&truth, &u[..n], noise_std)
            .ok()
            .map(|c| c.std.iter().map(|s| s * s).collect());
        out[i] = (theta_of(&ep), theta_of(&er), oe, bound);
    }
    out
}

/// Run the study sequentially; `progress(done)` is called after each run.
pub fn monte_carlo(cfg: &StudyConfig, mut progress: impl FnMut(u64)) -> StudyResult {
    let truth_p = PlantParams::PAPER;
    let names = param_names(truth_p.arx.na, truth_p.arx.nb);
    let truth = theta_of(&super::estimate_of(&truth_p));
    let p = truth.len();
    let k = cfg.ns.len();
    let mut acc: Vec<[Acc; 4]> = (0..k).map(|_| Default::default()).collect();
    for (done, s) in (cfg.first_seed..cfg.first_seed + cfg.seeds).enumerate() {
        for (i, (ep, er, oe, bound)) in one_run(cfg, s).into_iter().enumerate() {
            let [a_paper, a_rec, a_oe, a_crb] = &mut acc[i];
            a_paper.push(&ep, &truth);
            a_rec.push(&er, &truth);
            match oe {
                Some(f) => {
                    let est = theta_of(&f.estimate);
                    let se = f.uncertainty.std;
                    a_oe.covered.push(
                        (0..p)
                            .map(|j| (est[j] - truth[j]).abs() <= 1.96 * se[j])
                            .collect(),
                    );
                    a_oe.std_err.push(se);
                    a_oe.push(&est, &truth);
                }
                None => a_oe.failures += 1,
            }
            match bound {
                // Stored as a pseudo-error whose square is the CRB variance.
                Some(var) => {
                    let sd: Vec<f64> = var.iter().map(|v| v.sqrt()).collect();
                    let pseudo: Vec<f64> = truth.iter().zip(&sd).map(|(t, s)| t + s).collect();
                    a_crb.push(&pseudo, &truth);
                }
                None => a_crb.failures += 1,
            }
        }
        progress(done as u64 + 1);
    }
    let mut stats = Vec::new();
    for (i, a) in acc.iter().enumerate() {
        for (m, ai) in METHODS.iter().zip(a.iter()) {
            stats.push(ai.stats(m, cfg.ns[i], p));
        }
    }
    StudyResult {
        config: cfg.clone(),
        names,
        truth,
        stats,
    }
}

impl StudyResult {
    /// The statistics of `method` at `n`.
    pub fn get(&self, method: &str, n: usize) -> Option<&MethodStats> {
        self.stats.iter().find(|s| s.method == method && s.n == n)
    }

    /// One CSV row per method, N and parameter:
    /// `method,n,param,truth,rmse,rel_rmse,bias,coverage,rms_std_err,runs,failures` (empty fields where a
    /// statistic does not apply).
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "method,n,param,truth,rmse,rel_rmse,bias,coverage,rms_std_err,runs,failures\n",
        );
        let opt = |v: &Option<Vec<f64>>, i: usize| {
            v.as_ref()
                .map(|v| format!("{:?}", v[i]))
                .unwrap_or_default()
        };
        for st in &self.stats {
            for (i, name) in self.names.iter().enumerate() {
                s.push_str(&format!(
                    "{},{},{},{:?},{:?},{:?},{:?},{},{},{},{}\n",
                    st.method,
                    st.n,
                    name,
                    self.truth[i],
                    st.rmse[i],
                    st.rmse[i] / self.truth[i].abs(),
                    st.bias[i],
                    opt(&st.coverage, i),
                    opt(&st.rms_std_err, i),
                    st.runs,
                    st.failures
                ));
            }
        }
        s
    }

    /// A PNG grid: one log-log panel per parameter with the RMSE of each method against N, the CRB std
    /// dashed.
    pub fn plot(&self, path: &Path) -> Result<(), PlotError> {
        let labels = [
            "MRGIA (paper setting)",
            "MRGIA (recommended)",
            "output error (OE)",
            "Cramer-Rao bound std",
        ];
        let titles: Vec<String> = self
            .names
            .iter()
            .zip(&self.truth)
            .map(|(n, t)| format!("{n} (true {t})"))
            .collect();
        let mut ns = self.config.ns.clone();
        ns.sort_unstable();
        let panels: Vec<Panel> = titles
            .iter()
            .enumerate()
            .map(|(i, title)| {
                let series = METHODS
                    .iter()
                    .enumerate()
                    .flat_map(|(c, m)| {
                        let pts: Vec<(f64, f64)> = ns
                            .iter()
                            .filter_map(|&n| self.get(m, n).map(|s| (n as f64, s.rmse[i])))
                            .collect();
                        if *m == "crb" {
                            vec![Series::dashed(labels[c], pts).color(c)]
                        } else {
                            // A marker at each N (unlabelled: the line carries the legend).
                            vec![
                                Series::line(labels[c], pts.clone()).color(c),
                                Series::points("", pts).color(c),
                            ]
                        }
                    })
                    .collect();
                Panel {
                    title,
                    x_label: "samples N",
                    y_label: "RMSE",
                    series,
                    log_x: true,
                    log_y: true,
                }
            })
            .collect();
        grid_plot(
            path,
            &format!(
                "Paper 000 example, SNR {}: RMSE over {} runs against N",
                self.config.snr, self.config.seeds
            ),
            &panels,
            3,
        )
    }
}

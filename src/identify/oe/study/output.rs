//! A study's results as files: the tidy table and the summary as CSV, the convergence figure.

use std::path::Path;

use super::{GridResult, METHODS, MethodStats, ROWS_HEADER, StudyResult};
use crate::report::plot::{Panel, PlotError, Series, grid_plot};

impl GridResult {
    /// The tidy table as CSV ([`ROWS_HEADER`]; numbers round-trip exactly, empty fields where a value does
    /// not apply).
    pub fn rows_csv(&self) -> String {
        let opt = |v: Option<f64>| v.map(|x| format!("{x:?}")).unwrap_or_default();
        let mut s = String::with_capacity(self.rows.len() * 96 + 80);
        s.push_str(ROWS_HEADER);
        s.push('\n');
        for r in &self.rows {
            s.push_str(&format!(
                "{},{:?},{},{},{:?},{},{},{:?},{},{},{}\n",
                r.plant,
                r.snr,
                r.n,
                r.seed,
                r.noise_std,
                r.method,
                r.param,
                r.truth,
                opt(r.estimate),
                opt(r.error()),
                opt(r.std_err),
            ));
        }
        s
    }

    /// The aggregated statistics of every group as CSV: `plant,snr,` followed by [`StudyResult::to_csv`]'s
    /// columns.
    pub fn summary_csv(&self) -> String {
        let mut s = String::new();
        for (g, st) in self.groups.iter().enumerate() {
            for (i, line) in st.to_csv().lines().enumerate() {
                match (i, g) {
                    (0, 0) => s.push_str(&format!("plant,snr,{line}\n")),
                    (0, _) => {}
                    _ => s.push_str(&format!("{},{:?},{line}\n", st.plant, st.config.snr)),
                }
            }
        }
        s
    }

    /// The group of `plant` at `snr`.
    pub fn group(&self, plant: &str, snr: f64) -> Option<&StudyResult> {
        self.groups
            .iter()
            .find(|g| g.plant == plant && g.config.snr == snr)
    }
}

impl StudyResult {
    /// The statistics of `method` at `n`.
    pub fn get(&self, method: &str, n: usize) -> Option<&MethodStats> {
        self.stats.iter().find(|s| s.method == method && s.n == n)
    }

    /// One CSV row per method, N and parameter:
    /// `method,n,param,truth,rmse,rel_rmse,bias,coverage,rms_std_err,runs,failures,median_worst_crb,
    /// share_over_10_crb` (empty fields where a statistic does not apply; the last two are per method and N,
    /// repeated on each parameter's line).
    pub fn to_csv(&self) -> String {
        let mut s = String::from(
            "method,n,param,truth,rmse,rel_rmse,bias,coverage,rms_std_err,runs,failures,\
             median_worst_crb,share_over_10_crb\n",
        );
        let opt = |v: &Option<Vec<f64>>, i: usize| {
            v.as_ref()
                .map(|v| format!("{:?}", v[i]))
                .unwrap_or_default()
        };
        for st in &self.stats {
            for (i, name) in self.names.iter().enumerate() {
                s.push_str(&format!(
                    "{},{},{},{:?},{:?},{:?},{:?},{},{},{},{},{},{}\n",
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
                    st.failures,
                    st.crb_units
                        .map(|c| format!("{:?}", c.median))
                        .unwrap_or_default(),
                    st.crb_units
                        .map(|c| format!("{:?}", c.share_over_10))
                        .unwrap_or_default(),
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
            "MRGIA refine",
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
                        if pts.is_empty() {
                            vec![]
                        } else if *m == "crb" {
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
        let what = if self.plant == "paper" {
            "Paper 000 example".to_string()
        } else {
            format!("Plant '{}'", self.plant)
        };
        grid_plot(
            path,
            &format!(
                "{what}, SNR {}: RMSE over {} runs against N",
                self.config.snr, self.config.seeds
            ),
            &panels,
            3,
        )
    }
}

//! The loop of `backlash diagnose` on simulated test-bench records with several effects at once: for every
//! set of effects given, records from a range of seeds; prints one line per record and a summary per set
//! (how often each effect present was named, how often an effect not present was added, whether every step
//! lowered the held-out error).
//!
//! ```text
//! cargo run --release --example diagnose_loop -- [--seeds A..B] [--n N] [--max-effects K] SET...
//! ```
//! A SET is effect ids joined by `+` (`gap-drift+quantization`), or `clean`. `--json` prints each
//! record's diagnosis as the CLI's JSON too. The declared structure is the
//! paper's (na = 2, nb = 0, delay = 1).

use std::time::Instant;

use anyhow::{Context, Result, bail};
use backlash::diagnose::bench::{Scenario, names, scenario_with};
use backlash::diagnose::effects::EffectId;
use backlash::diagnose::engine::{DiagnoseConfig, Diagnosis, diagnose};

/// What one record showed.
struct Outcome {
    named: Vec<EffectId>,
    missed: Vec<EffectId>,
    extra: Vec<EffectId>,
    steps_lower: bool,
}

fn outcome(s: &Scenario, d: &Diagnosis) -> Outcome {
    let named: Vec<EffectId> = d.steps().iter().map(|c| c.id).collect();
    let mut before = d.base_heldout_rmse;
    let mut steps_lower = true;
    for c in d.steps() {
        // A noise model is judged by its one-step prediction error (its simulation is unchanged).
        let lower = match c.one_step {
            Some(o) => o.after < o.before,
            None => c.heldout_rmse < before,
        };
        steps_lower &= lower;
        before = c.heldout_rmse;
    }
    Outcome {
        missed: s
            .present
            .iter()
            .copied()
            .filter(|e| !named.contains(e))
            .collect(),
        extra: named
            .iter()
            .copied()
            .filter(|e| !s.present.contains(e))
            .collect(),
        named,
        steps_lower,
    }
}

fn parse_set(text: &str) -> Result<Vec<EffectId>> {
    if text == "clean" {
        return Ok(Vec::new());
    }
    text.split('+')
        .map(|t| EffectId::parse(t).with_context(|| format!("'{t}' is not an effect id")))
        .collect()
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let (mut seeds, mut n, mut max_effects, mut sets) = (0u64..10, 6000usize, 3usize, Vec::new());
    let mut json = false;
    while let Some(a) = args.next() {
        match a.as_str() {
            "--seeds" => {
                let v = args.next().context("--seeds needs A..B")?;
                let (lo, hi) = v.split_once("..").context("--seeds A..B")?;
                seeds = lo.parse()?..hi.parse()?;
            }
            "--n" => n = args.next().context("--n needs a number")?.parse()?,
            "--max-effects" => {
                max_effects = args
                    .next()
                    .context("--max-effects needs a number")?
                    .parse()?
            }
            "--json" => json = true,
            s => sets.push(parse_set(s)?),
        }
    }
    if sets.is_empty() {
        bail!("give at least one set of effects, e.g. gap-drift+quantization");
    }
    for set in &sets {
        let (mut present_named, mut present_total, mut extra, mut lower, mut records) =
            (0usize, 0usize, 0usize, 0usize, 0usize);
        let t0 = Instant::now();
        for seed in seeds.clone() {
            let s = scenario_with(set, seed, n);
            let mut cfg = DiagnoseConfig::new(s.declared.0, s.declared.1, s.declared.2);
            cfg.max_effects = max_effects;
            let t = Instant::now();
            let d = diagnose(&s.u, &s.y, &cfg)?;
            let o = outcome(&s, &d);
            if json {
                println!("{}", d.to_json(None));
            }
            records += 1;
            present_total += set.len();
            present_named += set.len() - o.missed.len();
            extra += usize::from(!o.extra.is_empty());
            lower += usize::from(o.steps_lower);
            let errors: Vec<String> = std::iter::once(d.base_heldout_rmse)
                .chain(d.steps().iter().map(|c| c.heldout_rmse))
                .map(|v| format!("{v:.4}"))
                .collect();
            println!(
                "{:<40} seed {seed:>6}: {:<45} {} [{:.1} s]{}{}",
                names(set),
                names(&o.named),
                errors.join(" -> "),
                t.elapsed().as_secs_f64(),
                if o.missed.is_empty() {
                    String::new()
                } else {
                    format!(" missed {}", names(&o.missed))
                },
                if o.extra.is_empty() {
                    String::new()
                } else {
                    format!(" EXTRA {}", names(&o.extra))
                },
            );
        }
        println!(
            "== {}: {present_named}/{present_total} effects present named, {extra}/{records} records with an \
             effect not present, every step lower in {lower}/{records} ({:.0} s)",
            names(set),
            t0.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

//! The model-structure options: declared or chosen (`diagnose`, `identify oe`), or declared only (the on-line
//! estimator's commands, `identify mrgia` and `monitor`).

use anyhow::{Result, bail};
// Through the API's name: a path through the library's `diagnose` would read, to a reader that resolves
// module names, as an import of this program's own `diagnose` module, which imports this one.
use backlash::api::Structure;
use backlash::plant::MAX_DELAY;

/// The structure the on-line estimator runs with: all three of `--na`, `--nb` and `--delay`.
#[derive(clap::Args, Debug, Clone)]
pub struct OrderArgs {
    /// Number of a coefficients (0 to 4).
    #[arg(long)]
    pub na: usize,
    /// Highest b index (0 to 4): b0..b_nb are estimated.
    #[arg(long)]
    pub nb: usize,
    /// Input delay in samples (1 to 64).
    #[arg(long)]
    pub delay: usize,
}

/// Declared with all three of `--na`, `--nb` and `--delay`, or chosen from the data.
#[derive(clap::Args, Debug, Clone)]
pub struct StructureArgs {
    /// Number of a coefficients of the declared model (0 to 4). Without --na, --nb and --delay the
    /// structure is chosen from the fit part of the data.
    #[arg(long, requires_all = ["nb", "delay"])]
    pub na: Option<usize>,
    /// Highest b index of the declared model (0 to 4): b0 to b_nb are estimated.
    #[arg(long, requires_all = ["na", "delay"])]
    pub nb: Option<usize>,
    /// Input delay of the declared model, in samples (after decimation where the command decimates; 1 to
    /// 64).
    #[arg(long, requires_all = ["na", "nb"])]
    pub delay: Option<usize>,
    /// The longest delay the structure selection tries, in samples (1 to 64).
    #[arg(long, default_value_t = 10)]
    pub max_delay: usize,
}

impl StructureArgs {
    /// The declared structure, if all three were given.
    pub fn declared(&self) -> Option<Structure> {
        match (self.na, self.nb, self.delay) {
            (Some(na), Some(nb), Some(delay)) => Some(Structure { na, nb, delay }),
            _ => None,
        }
    }

    /// `--max-delay`, checked.
    pub fn max_delay(&self) -> Result<usize> {
        if !(1..=MAX_DELAY).contains(&self.max_delay) {
            bail!(
                "--max-delay {} must be between 1 and {MAX_DELAY}",
                self.max_delay
            );
        }
        Ok(self.max_delay)
    }
}

//! `backlash simulate`: the plant of the library on an input CSV.

use anyhow::{Context, Result};
use backlash::api::{PlantSpec, simulate};
use backlash::io::{Table, write_atomic};
use std::io::Write;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct SimulateArgs {
    /// Input CSV with columns time,u (other columns are ignored).
    pub input: PathBuf,
    /// Output CSV (time,u,x,w,y); standard output if omitted.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Plant parameters as JSON (the keys of the flags below, e.g. {"a":[0.45,0.55],"b":[0.8],"m2":1.5});
    /// flags given on the command line override the file.
    #[arg(long)]
    pub params: Option<PathBuf>,
    #[command(flatten)]
    pub plant: PlantFlags,
}

/// Plant parameters on the command line; unset ones come from --params, else from paper 000's example.
#[derive(clap::Args, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantFlags {
    /// Linear block: a1..a_na, comma-separated (na is their number).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub a: Option<Vec<f64>>,
    /// Linear block: b0..b_nb, comma-separated (nb + 1 values).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub b: Option<Vec<f64>>,
    /// Input delay in samples (>= 1).
    #[arg(long)]
    pub delay: Option<usize>,
    /// Slope of the upper border.
    #[arg(long, allow_negative_numbers = true)]
    pub m1: Option<f64>,
    /// Slope of the lower border.
    #[arg(long, allow_negative_numbers = true)]
    pub m2: Option<f64>,
    /// Gap of the upper border.
    #[arg(long, allow_negative_numbers = true)]
    pub c1: Option<f64>,
    /// Gap of the lower border.
    #[arg(long, allow_negative_numbers = true)]
    pub c2: Option<f64>,
    /// Standard deviation of the measurement noise on y.
    #[arg(long, allow_negative_numbers = true)]
    pub noise_std: Option<f64>,
    /// Seed of the noise.
    #[arg(long)]
    pub noise_seed: Option<u64>,
}

impl PlantFlags {
    /// Fields set here win over `base`.
    fn over(self, base: PlantFlags) -> PlantFlags {
        PlantFlags {
            a: self.a.or(base.a),
            b: self.b.or(base.b),
            delay: self.delay.or(base.delay),
            m1: self.m1.or(base.m1),
            m2: self.m2.or(base.m2),
            c1: self.c1.or(base.c1),
            c2: self.c2.or(base.c2),
            noise_std: self.noise_std.or(base.noise_std),
            noise_seed: self.noise_seed.or(base.noise_seed),
        }
    }

    fn spec(self) -> PlantSpec {
        PlantSpec {
            a: self.a,
            b: self.b,
            delay: self.delay,
            m1: self.m1,
            m2: self.m2,
            c1: self.c1,
            c2: self.c2,
            noise_std: self.noise_std,
            noise_seed: self.noise_seed,
        }
    }
}

pub fn run(args: &SimulateArgs) -> Result<()> {
    let base = match &args.params {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("{}: cannot read", path.display()))?;
            serde_json::from_str::<PlantFlags>(&text)
                .with_context(|| format!("{}: not a valid parameter file", path.display()))?
        }
        None => PlantFlags::default(),
    };
    let flags = PlantFlags {
        a: args.plant.a.clone(),
        b: args.plant.b.clone(),
        ..args.plant
    };
    let spec = flags.over(base).spec();
    spec.params()?;
    let table = Table::read(&args.input, &["time", "u"])?;
    let (t, u) = (table.column("time").unwrap(), table.column("u").unwrap());
    let out = simulate(&spec, u)?;
    let write = |w: &mut dyn Write| -> std::io::Result<()> {
        writeln!(w, "time,u,x,w,y")?;
        for ((t, u), o) in t.iter().zip(u).zip(&out) {
            writeln!(w, "{t:?},{u:?},{:?},{:?},{:?}", o.x, o.w, o.y)?;
        }
        Ok(())
    };
    match &args.output {
        Some(path) => write_atomic(path, write)
            .with_context(|| format!("{}: cannot write", path.display()))?,
        None => write(&mut std::io::stdout().lock())?,
    }
    Ok(())
}

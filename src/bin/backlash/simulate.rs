//! `backlash simulate`: the plant of the library on an input CSV.

use anyhow::{Context, Result};
use backlash::api::{PlantSpec, Record, simulate};
use backlash::io::write_atomic;
use backlash::plant::PlantOutput;
use std::io::Write;
use std::path::PathBuf;

use super::common::{PlantArgs, RecordArgs, spec_file};

#[derive(clap::Args)]
pub struct SimulateArgs {
    /// Input CSV with columns time,u (other columns are ignored).
    pub input: PathBuf,
    /// Output CSV (time,u,x,w,y); standard output if omitted.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Plant parameters as a JSON object under the FMU's names (e.g. {"a":[0.45,0.55],"b":[0.8],"m2":1.5,
    /// "c1_rate":0.01}); flags given on the command line override the file.
    #[arg(long)]
    pub params: Option<PathBuf>,
    #[command(flatten)]
    pub record: RecordArgs,
    #[command(flatten)]
    pub plant: PlantArgs,
}

/// The flags over the file; the sample period `Ts`, unless given, is the record's (median) time step.
fn spec(args: &SimulateArgs, rec: &Record) -> Result<PlantSpec> {
    let mut spec = args
        .plant
        .spec
        .clone()
        .over(&spec_file(args.params.as_deref())?);
    if !spec.has("Ts")
        && let Some(ts) = rec.sample_period()
    {
        spec.set("Ts", ts)?;
    }
    Ok(spec)
}

pub fn run(args: &SimulateArgs) -> Result<()> {
    let rec = args.record.options().read(&args.input, false)?;
    let out = simulate(&spec(args, &rec)?, &rec.u)?;
    let write = |w: &mut dyn Write| write_csv(w, &rec, &out);
    match &args.output {
        Some(path) => write_atomic(path, write)
            .with_context(|| format!("{}: cannot write", path.display()))?,
        None => write(&mut std::io::stdout().lock())?,
    }
    Ok(())
}

fn write_csv(w: &mut dyn Write, rec: &Record, out: &[PlantOutput]) -> std::io::Result<()> {
    writeln!(w, "time,u,x,w,y")?;
    for ((t, u), o) in rec.t.iter().zip(&rec.u).zip(out) {
        writeln!(w, "{t:?},{u:?},{:?},{:?},{:?}", o.x, o.w, o.y)?;
    }
    Ok(())
}

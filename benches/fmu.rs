//! Cost of one co-simulation step as a simulation tool sees it: the built FMUs loaded from their .fmu files by
//! the `fmi` crate (an importer nobody here wrote; it unpacks the archive, dlopens the binary and calls it
//! through function pointers), per step `fmi2SetReal`, `fmi2DoStep`, `fmi2GetReal`.
//!
//! `BACKLASH_FMU=always cargo build --release && cargo bench --bench fmu` (the FMUs are read from
//! target/fmu, or from `$BACKLASH_FMU_DIR`; a missing FMU stops the bench with that instruction).
//!
//! Group "fmu step", per step (criterion's throughput is steps/s):
//! - baseline: the same work in-process without FMI, `Plant::advance` then `Mrgia::update` on the library;
//! - plant FMU alone: set u, doStep, get y;
//! - estimator FMU alone: set u and y (a recorded paper-example output), doStep, get the six estimates;
//! - the same with `refine = true`, getting the six estimates and their six standard errors (the instance runs
//!   on over the iterations, so this is the recursion's steady state after its start in the first);
//! - the pair: plant get y(k), set u(k); estimator set u(k), y(k); both doStep; estimator get the six
//!   estimates;
//! - the compensator FMU alone: set r, m2, c1, c2 (the paper's backlash), get v, doStep; and the library's
//!   `BacklashInverse::commit` on the same references, in-process.
//!
//! The FMI cost of a step is the FMU figure minus the library's share, measured in the same run.

use backlash::compensate::BacklashInverse;
use backlash::identify::mrgia::{Mrgia, MrgiaConfig, paper_input};
use backlash::plant::{BacklashParams, Plant, PlantParams};
use criterion::measurement::WallTime;
use criterion::{
    BatchSize, BenchmarkGroup, Criterion, Throughput, criterion_group, criterion_main,
};
use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation, Common, InstanceCS};
use fmi::traits::FmiImport;
use std::hint::black_box;
use std::path::PathBuf;

/// Steps per criterion iteration.
const STEPS: usize = 1000;

fn fmu(name: &str) -> PathBuf {
    let dir = std::env::var_os("BACKLASH_FMU_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/fmu"));
    let p = dir.join(format!("{name}.fmu"));
    if !p.exists() {
        panic!(
            "{} is missing: build the FMUs with `BACKLASH_FMU=always cargo build --release` (they land in \
             $CARGO_TARGET_DIR/fmu, default target/fmu) and point BACKLASH_FMU_DIR at that directory if it is \
             not target/fmu",
            p.display()
        );
    }
    p
}

fn vr(import: &Fmi2Import, name: &str) -> u32 {
    import
        .model_description()
        .model_variables
        .variables
        .iter()
        .find(|v| v.name == name)
        .unwrap_or_else(|| panic!("no variable {name}"))
        .value_reference
}

/// An initialised co-simulation instance and its running time.
struct Slave {
    inst: InstanceCS,
    t: f64,
}

impl Slave {
    fn new(import: &Fmi2Import, name: &str) -> Self {
        Self::with(import, name, |_| {})
    }

    /// With `set` applied to the parameters before initialisation.
    fn with(import: &Fmi2Import, name: &str, set: impl FnOnce(&mut InstanceCS)) -> Self {
        let mut inst = import
            .instantiate_cs(name, false, false)
            .expect("instantiate");
        set(&mut inst);
        inst.setup_experiment(None, 0.0, None).expect("setup");
        inst.enter_initialization_mode().expect("init");
        inst.exit_initialization_mode().expect("init");
        Slave { inst, t: 0.0 }
    }

    #[inline]
    fn step(&mut self) {
        self.inst.do_step(self.t, 1.0, true).expect("doStep");
        self.t += 1.0;
    }
}

/// The two FMUs as loaded, and the value references the benchmarks use.
struct Fmus {
    plant: Fmi2Import,
    est: Fmi2Import,
    /// Plant input u and output y.
    pu: u32,
    py: u32,
    /// Estimator inputs u and y, and the six estimates.
    eu: u32,
    ey: u32,
    outs: Vec<u32>,
}

impl Fmus {
    fn load() -> Fmus {
        let plant: Fmi2Import =
            fmi::import::from_path(fmu("BacklashPlant")).expect("BacklashPlant.fmu loads");
        let est: Fmi2Import =
            fmi::import::from_path(fmu("MrgiaEstimator")).expect("MrgiaEstimator.fmu loads");
        let (pu, py) = (vr(&plant, "u"), vr(&plant, "y"));
        let (eu, ey) = (vr(&est, "u"), vr(&est, "y"));
        let outs: Vec<u32> = ["a1", "a2", "b0", "m2", "c1", "c2"]
            .iter()
            .map(|n| vr(&est, n))
            .collect();
        Fmus {
            plant,
            est,
            pu,
            py,
            eu,
            ey,
            outs,
        }
    }
}

type Group<'a> = BenchmarkGroup<'a, WallTime>;

fn fmu_step(c: &mut Criterion) {
    let fmus = Fmus::load();
    let u = paper_input(STEPS, 3);
    let y: Vec<f64> = Plant::simulate(PlantParams::PAPER, &u)
        .expect("the paper plant is valid")
        .iter()
        .map(|o| o.y)
        .collect();

    let mut g = c.benchmark_group("fmu step");
    g.throughput(Throughput::Elements(STEPS as u64));
    library_baseline(&mut g, &u);
    plant_alone(&mut g, &fmus, &u);
    estimator_alone(&mut g, &fmus, &u, &y);
    estimator_refine(&mut g, &fmus, &u, &y);
    pair(&mut g, &fmus, &u);
    compensator(&mut g, &u);
    g.finish();
}

/// The same work in-process without FMI: `Plant::advance` then `Mrgia::update` on the library.
fn library_baseline(g: &mut Group, u: &[f64]) {
    g.bench_function("library plant + estimator, no FMI (baseline)", |b| {
        b.iter_batched(
            || {
                (
                    Plant::new(PlantParams::PAPER).unwrap(),
                    Mrgia::new(MrgiaConfig::paper(2, 0, 1)).unwrap(),
                )
            },
            |(mut p, mut m)| {
                for &uk in u {
                    let yk = p.output().y;
                    p.advance(black_box(uk));
                    m.update(uk, yk);
                }
                m.theta()[0]
            },
            BatchSize::SmallInput,
        )
    });
}

/// The plant FMU alone: set u, doStep, get y.
fn plant_alone(g: &mut Group, fmus: &Fmus, u: &[f64]) {
    let (pu, py) = (fmus.pu, fmus.py);
    let mut plant = Slave::new(&fmus.plant, "plant");
    g.bench_function("plant FMU: set u, doStep, get y", |b| {
        b.iter(|| {
            let mut out = [0.0];
            for &uk in u {
                plant.inst.set_real(&[pu], &[black_box(uk)]).unwrap();
                plant.step();
                plant.inst.get_real(&[py], &mut out).unwrap();
            }
            out[0]
        })
    });
}

/// The estimator FMU alone: set u and y (a recorded paper-example output), doStep, get the six estimates.
fn estimator_alone(g: &mut Group, fmus: &Fmus, u: &[f64], y: &[f64]) {
    let (eu, ey, outs) = (fmus.eu, fmus.ey, &fmus.outs);
    let mut est = Slave::new(&fmus.est, "estimator");
    g.bench_function("estimator FMU: set u y, doStep, get 6 estimates", |b| {
        b.iter(|| {
            let mut out = [0.0; 6];
            for k in 0..STEPS {
                est.inst
                    .set_real(&[eu, ey], &[black_box(u[k]), y[k]])
                    .unwrap();
                est.step();
                est.inst.get_real(outs, &mut out).unwrap();
            }
            out[0]
        })
    });
}

/// The estimator FMU with `refine = true`, getting the six estimates and their six standard errors.
fn estimator_refine(g: &mut Group, fmus: &Fmus, u: &[f64], y: &[f64]) {
    let (eu, ey, est_import) = (fmus.eu, fmus.ey, &fmus.est);
    let refine = vr(est_import, "refine");
    let se_outs: Vec<u32> = ["a1", "a2", "b0", "m2", "c1", "c2"]
        .iter()
        .map(|n| vr(est_import, n))
        .chain(
            ["a1_se", "a2_se", "b0_se", "m2_se", "c1_se", "c2_se"]
                .iter()
                .map(|n| vr(est_import, n)),
        )
        .collect();
    let mut est = Slave::with(est_import, "estimator-refine", |i| {
        i.set_boolean(&[refine], &[1]).expect("set refine");
    });
    g.bench_function(
        "estimator FMU, refine: set u y, doStep, get 6 estimates and 6 standard errors",
        |b| {
            b.iter(|| {
                let mut out = [0.0; 12];
                for k in 0..STEPS {
                    est.inst
                        .set_real(&[eu, ey], &[black_box(u[k]), y[k]])
                        .unwrap();
                    est.step();
                    est.inst.get_real(&se_outs, &mut out).unwrap();
                }
                out[0]
            })
        },
    );
}

/// The pair: plant get y(k), set u(k); estimator set u(k), y(k); both doStep; estimator get the six
/// estimates.
fn pair(g: &mut Group, fmus: &Fmus, u: &[f64]) {
    let (pu, py, eu, ey, outs) = (fmus.pu, fmus.py, fmus.eu, fmus.ey, &fmus.outs);
    let mut plant = Slave::new(&fmus.plant, "plant2");
    let mut est = Slave::new(&fmus.est, "estimator2");
    g.bench_function("pair: plant + estimator, with get/set", |b| {
        b.iter(|| {
            let (mut yk, mut out) = ([0.0], [0.0; 6]);
            for &uk in u {
                // y(k) at t_k, before the plant steps over sample k (as tests/python/cosim.py pairs them).
                plant.inst.get_real(&[py], &mut yk).unwrap();
                plant.inst.set_real(&[pu], &[black_box(uk)]).unwrap();
                est.inst.set_real(&[eu, ey], &[uk, yk[0]]).unwrap();
                plant.step();
                est.step();
                est.inst.get_real(outs, &mut out).unwrap();
            }
            out[0]
        })
    });
}

/// The compensator FMU alone (set r and the estimate, get v, doStep) and the library's inverse it wraps, on
/// the paper input as the reference.
fn compensator(g: &mut Group, r: &[f64]) {
    let import: Fmi2Import =
        fmi::import::from_path(fmu("BacklashCompensator")).expect("BacklashCompensator.fmu loads");
    let inputs: Vec<u32> = ["r", "m2", "c1", "c2"]
        .iter()
        .map(|n| vr(&import, n))
        .collect();
    let v = vr(&import, "v");
    let p = BacklashParams::PAPER;
    let mut comp = Slave::new(&import, "compensator");
    g.bench_function("compensator FMU: set r m2 c1 c2, get v, doStep", |b| {
        b.iter(|| {
            let mut out = [0.0];
            for &rk in r {
                comp.inst
                    .set_real(&inputs, &[black_box(rk), p.m2, p.c1, p.c2])
                    .unwrap();
                comp.inst.get_real(&[v], &mut out).unwrap();
                comp.step();
            }
            out[0]
        })
    });
    g.bench_function("library backlash inverse commit, no FMI", |b| {
        b.iter_batched(
            || BacklashInverse::new(0.0).unwrap(),
            |mut inv| {
                r.iter()
                    .map(|&rk| inv.commit(black_box(rk), &p).v)
                    .sum::<f64>()
            },
            BatchSize::SmallInput,
        )
    });
}

criterion_group!(benches, fmu_step);
criterion_main!(benches);

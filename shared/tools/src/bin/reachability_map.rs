//! Reachability map (thesis Fig. 7.10): for a grid of positions and a fixed set of
//! sampled orientations, count how many orientations the IK reaches at each position.
//! Writes `<robot>_reachability.csv` (x, y, z, reached, sampled) and a PNG with a top
//! view (x-y, best cell over z) and a side view (x-z, best cell over y), coloured as
//! in the thesis: blue > 50, green > 20, yellow > 10, red >= 1 orientations.
//!
//! `cargo run --release -p teleop-ik --bin reachability_map -- --robot ur5 --out-dir docs/img`

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Parser, ValueEnum};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use teleop_ik::{ColdBudget, Goal, IkSettings, Solver};
use teleop_kinematics::robots;

#[derive(Debug, Clone, Copy, ValueEnum)]
enum RobotArg {
    /// UR5 flange (6 joints), base frame at the shoulder.
    Ur5,
    /// PR2 right arm + Shadow wrist (7 joints), base_link on the floor.
    Pr2,
}

#[derive(Debug, Parser)]
#[command(about = "Count IK-reachable orientations on a grid of positions")]
struct Cli {
    #[arg(long, value_enum, default_value_t = RobotArg::Ur5)]
    robot: RobotArg,
    /// Grid spacing, metres.
    #[arg(long, default_value_t = 0.1)]
    resolution_m: f64,
    /// Orientations sampled per position (the same set at every position).
    #[arg(long, default_value_t = 100)]
    orientations: usize,
    /// Random restarts per IK query.
    #[arg(long, default_value_t = 8)]
    restarts: u32,
    /// Seed of the orientation sample and the IK restarts.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output directory.
    #[arg(long, default_value = ".")]
    out_dir: PathBuf,
}

/// Uniformly distributed rotations (Shoemake's method) from a seeded SplitMix64.
fn sample_rotations(n: usize, seed: u64) -> Vec<UnitQuaternion<f64>> {
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| {
            let (u1, u2, u3) = (next(), next(), next());
            let tau = std::f64::consts::TAU;
            let a = (1.0 - u1).sqrt();
            let b = u1.sqrt();
            UnitQuaternion::new_normalize(nalgebra::Quaternion::new(
                b * (tau * u3).cos(),
                a * (tau * u2).sin(),
                a * (tau * u2).cos(),
                b * (tau * u3).sin(),
            ))
        })
        .collect()
}

struct Grid {
    min: Vector3<f64>,
    dims: [usize; 3],
    step: f64,
}

impl Grid {
    fn point(&self, i: usize, j: usize, k: usize) -> Vector3<f64> {
        self.min + Vector3::new(i as f64, j as f64, k as f64) * self.step
    }
}

fn map<const N: usize>(
    solver: &Solver<N>,
    grid: &Grid,
    rotations: &[UnitQuaternion<f64>],
    restarts: u32,
    seed: u64,
) -> Vec<usize> {
    let [nx, ny, nz] = grid.dims;
    let mut counts = vec![0; nx * ny * nz];
    let budget = ColdBudget {
        max_restarts: restarts,
        time_limit: None,
    };
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = grid.point(i, j, k);
                let mut reached = 0;
                for (r, rot) in rotations.iter().enumerate() {
                    let target = Isometry3::from_parts(Translation3::from(p), *rot);
                    let s = seed ^ ((((k * ny + j) * nx + i) * rotations.len() + r) as u64);
                    if solver
                        .solve_cold(&[Goal::pose(target)], None, s, budget)
                        .is_ok()
                    {
                        reached += 1;
                    }
                }
                counts[(k * ny + j) * nx + i] = reached;
            }
        }
        eprintln!("layer {}/{nz} done", k + 1);
    }
    counts
}

fn class_colour(count: usize) -> [u8; 3] {
    match count {
        c if c > 50 => [40, 90, 220],
        c if c > 20 => [40, 170, 70],
        c if c > 10 => [235, 200, 40],
        c if c >= 1 => [220, 50, 40],
        _ => [245, 245, 245],
    }
}

fn write_png(path: &Path, grid: &Grid, counts: &[usize]) -> anyhow::Result<()> {
    let [nx, ny, nz] = grid.dims;
    let cell = 12usize;
    let gap = 16usize;
    let width = (nx * 2) * cell + gap;
    let height = ny.max(nz) * cell;
    let mut img = vec![255u8; width * height * 3];
    let mut put = |x0: usize, y0: usize, c: [u8; 3]| {
        for y in y0..y0 + cell {
            for x in x0..x0 + cell {
                let o = (y * width + x) * 3;
                if o + 2 < img.len() {
                    img[o..o + 3].copy_from_slice(&c);
                }
            }
        }
    };
    let at = |i: usize, j: usize, k: usize| counts[(k * ny + j) * nx + i];
    // Top view: x to the right, y up; best over z.
    for j in 0..ny {
        for i in 0..nx {
            let best = (0..nz).map(|k| at(i, j, k)).max().unwrap_or(0);
            put(i * cell, (ny - 1 - j) * cell, class_colour(best));
        }
    }
    // Side view: x to the right, z up; best over y.
    for k in 0..nz {
        for i in 0..nx {
            let best = (0..ny).map(|j| at(i, j, k)).max().unwrap_or(0);
            put(
                nx * cell + gap + i * cell,
                (ny.max(nz) - 1 - k) * cell,
                class_colour(best),
            );
        }
    }
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), width as u32, height as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header()?;
    w.write_image_data(&img)?;
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    if !(cli.resolution_m.is_finite() && cli.resolution_m >= 0.01) {
        bail!("--resolution-m must be >= 0.01 m, got {}", cli.resolution_m);
    }
    if cli.orientations == 0 {
        bail!("--orientations must be at least 1");
    }
    std::fs::create_dir_all(&cli.out_dir)
        .with_context(|| format!("creating {}", cli.out_dir.display()))?;
    let rotations = sample_rotations(cli.orientations, cli.seed);
    let settings = IkSettings {
        // A map counts reachability, not precision: 1 mm / ~0.06 deg.
        position_tolerance_m: 1e-3,
        orientation_tolerance_rad: 1e-3,
        ..IkSettings::default()
    };
    let (name, counts, grid) = match cli.robot {
        RobotArg::Ur5 => {
            // UR5 reach is 0.85 m around the shoulder.
            let grid = grid_for(
                Vector3::new(-1.0, -1.0, -0.8),
                Vector3::new(1.0, 1.0, 1.2),
                cli.resolution_m,
            );
            let solver = Solver::new(robots::ur5_flange_chain()?, settings);
            (
                "ur5",
                map(&solver, &grid, &rotations, cli.restarts, cli.seed),
                grid,
            )
        }
        RobotArg::Pr2 => {
            // Right arm reach around the shoulder at (~0, -0.19, ~0.74+torso).
            let grid = grid_for(
                Vector3::new(-0.8, -1.3, 0.0),
                Vector3::new(1.2, 0.7, 1.8),
                cli.resolution_m,
            );
            let solver = Solver::new(robots::pr2_arm_chain()?, settings);
            (
                "pr2",
                map(&solver, &grid, &rotations, cli.restarts, cli.seed),
                grid,
            )
        }
    };
    let csv_path = cli.out_dir.join(format!("{name}_reachability.csv"));
    let mut csv = std::io::BufWriter::new(
        std::fs::File::create(&csv_path)
            .with_context(|| format!("creating {}", csv_path.display()))?,
    );
    writeln!(csv, "x_m,y_m,z_m,reached,sampled")?;
    let [nx, ny, nz] = grid.dims;
    let mut histogram = [0usize; 5];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = grid.point(i, j, k);
                let c = counts[(k * ny + j) * nx + i];
                writeln!(
                    csv,
                    "{:.3},{:.3},{:.3},{c},{}",
                    p.x,
                    p.y,
                    p.z,
                    rotations.len()
                )?;
                let class = match c {
                    c if c > 50 => 0,
                    c if c > 20 => 1,
                    c if c > 10 => 2,
                    c if c >= 1 => 3,
                    _ => 4,
                };
                histogram[class] += 1;
            }
        }
    }
    let png_path = cli.out_dir.join(format!("{name}_reachability.png"));
    write_png(&png_path, &grid, &counts)?;
    println!(
        "{name}: {} positions x {} orientations; >50: {}, >20: {}, >10: {}, >=1: {}, none: {}",
        counts.len(),
        rotations.len(),
        histogram[0],
        histogram[1],
        histogram[2],
        histogram[3],
        histogram[4]
    );
    println!("wrote {} and {}", csv_path.display(), png_path.display());
    Ok(())
}

fn grid_for(min: Vector3<f64>, max: Vector3<f64>, step: f64) -> Grid {
    let n = |a: f64, b: f64| (((b - a) / step).floor() as usize) + 1;
    Grid {
        min,
        dims: [n(min.x, max.x), n(min.y, max.y), n(min.z, max.z)],
        step,
    }
}

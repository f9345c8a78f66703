//! Reachability map (thesis Fig. 7.10): for a grid of positions and a fixed set of
//! sampled orientations, count how many orientations the IK reaches at each position.
//! Writes `<robot>_reachability.csv` (x, y, z, reached, sampled) and a PNG with a top
//! view (x-y, best cell over z) and a side view (x-z, best cell over y), coloured as
//! in the thesis: blue > 50, green > 20, yellow > 10, red >= 1 orientations.
//!
//! `cargo run --release -p teleop-tools --bin reachability_map -- --robot ur5 --out-dir docs/img`

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::{Parser, ValueEnum};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
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

/// The colour classes of thesis Fig. 7.10, best first: (lowest count, colour, legend).
const CLASSES: [(usize, RGBColor, &str); 4] = [
    (51, RGBColor(40, 90, 220), "more than 50"),
    (21, RGBColor(40, 170, 70), "21 to 50"),
    (11, RGBColor(235, 200, 40), "11 to 20"),
    (1, RGBColor(220, 50, 40), "1 to 10"),
];
/// Cells where no orientation was reached.
const NONE_COLOUR: RGBColor = RGBColor(240, 240, 240);
const FONT: &str = teleop_node::plot::FONT_FAMILY;

fn class_colour(count: usize) -> RGBColor {
    CLASSES
        .iter()
        .find(|(min, _, _)| count >= *min)
        .map_or(NONE_COLOUR, |(_, colour, _)| *colour)
}

/// One view of the map: cells (centre on the horizontal axis, centre on the vertical
/// axis, count) on a square grid of `step`.
struct View {
    title: &'static str,
    axes: [&'static str; 2],
    range: [(f64, f64); 2],
    cells: Vec<(f64, f64, usize)>,
}

/// Top view (x-y, best over z) left and side view (x-z, best over y) right, at the
/// same scale in both axes and both views, with a legend of the colour classes.
fn write_png(
    path: &Path,
    robot: &str,
    grid: &Grid,
    counts: &[usize],
    sampled: usize,
) -> anyhow::Result<()> {
    teleop_node::plot::register_fonts()?;
    let [nx, ny, nz] = grid.dims;
    let at = |i: usize, j: usize, k: usize| counts[(k * ny + j) * nx + i];
    let half = grid.step / 2.0;
    let span = |axis: usize, n: usize| {
        (
            grid.min[axis] - half,
            grid.min[axis] + (n as f64 - 1.0) * grid.step + half,
        )
    };
    let mut top = View {
        title: "Top view (x-y), best cell over z",
        axes: ["x (m)", "y (m)"],
        range: [span(0, nx), span(1, ny)],
        cells: Vec::with_capacity(nx * ny),
    };
    for j in 0..ny {
        for i in 0..nx {
            let best = (0..nz).map(|k| at(i, j, k)).max().unwrap_or(0);
            let p = grid.point(i, j, 0);
            top.cells.push((p.x, p.y, best));
        }
    }
    let mut side = View {
        title: "Side view (x-z), best cell over y",
        axes: ["x (m)", "z (m)"],
        range: [span(0, nx), span(2, nz)],
        cells: Vec::with_capacity(nx * nz),
    };
    for k in 0..nz {
        for i in 0..nx {
            let best = (0..ny).map(|j| at(i, j, k)).max().unwrap_or(0);
            let p = grid.point(i, 0, k);
            side.cells.push((p.x, p.z, best));
        }
    }

    let root = BitMapBackend::new(path, (1400, 780)).into_drawing_area();
    root.fill(&WHITE)?;
    let root = root.margin(8, 0, 0, 0).titled(
        &format!(
            "{robot} reachability map: orientations reached out of {sampled} per position, \
             {} m grid",
            grid.step
        ),
        (FONT, 26),
    )?;
    let (charts, legend) = root.split_vertically(root.dim_in_pixel().1.saturating_sub(50));
    let (left, right) = charts.split_horizontally(charts.dim_in_pixel().0 / 2);
    let views = [(left, top), (right, side)];
    // Titles first, then one scale (pixels per metre) that fits both views.
    let (x_label_px, y_label_px, margin_px) = (50u32, 70u32, 15u32);
    let mut titled = Vec::new();
    for (area, view) in views {
        titled.push((area.titled(view.title, (FONT, 20))?, view));
    }
    let px_per_m = titled
        .iter()
        .map(|(area, view)| {
            let (w, h) = area.dim_in_pixel();
            let pw = f64::from(w.saturating_sub(y_label_px + 2 * margin_px));
            let ph = f64::from(h.saturating_sub(x_label_px + 2 * margin_px));
            let (wx, wy) = (
                view.range[0].1 - view.range[0].0,
                view.range[1].1 - view.range[1].0,
            );
            f64::min(pw / wx, ph / wy)
        })
        .fold(f64::INFINITY, f64::min);
    for (area, view) in &titled {
        draw_view(
            area,
            view,
            px_per_m,
            grid.step,
            (x_label_px, y_label_px, margin_px),
        )?;
    }
    draw_legend(&legend)?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// One view as a chart whose plotting area is `px_per_m` pixels per metre in both axes,
/// centred in `area`.
fn draw_view(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    view: &View,
    px_per_m: f64,
    step: f64,
    (x_label_px, y_label_px, margin_px): (u32, u32, u32),
) -> anyhow::Result<()> {
    let (w, h) = area.dim_in_pixel();
    let [(x0, x1), (y0, y1)] = view.range;
    let pw = ((x1 - x0) * px_per_m).round() as u32;
    let ph = ((y1 - y0) * px_per_m).round() as u32;
    let spare_w = w.saturating_sub(pw + y_label_px + 2 * margin_px);
    let spare_h = h.saturating_sub(ph + x_label_px + 2 * margin_px);
    let mut chart = ChartBuilder::on(area)
        .margin_left(margin_px + spare_w / 2)
        .margin_right(margin_px + spare_w - spare_w / 2)
        .margin_top(margin_px + spare_h / 2)
        .margin_bottom(margin_px + spare_h - spare_h / 2)
        .x_label_area_size(x_label_px)
        .y_label_area_size(y_label_px)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    let half = step / 2.0;
    chart.draw_series(view.cells.iter().map(|&(x, y, count)| {
        Rectangle::new(
            [(x - half, y - half), (x + half, y + half)],
            class_colour(count).filled(),
        )
    }))?;
    chart
        .configure_mesh()
        .x_desc(view.axes[0])
        .y_desc(view.axes[1])
        .x_label_formatter(&teleop_node::plot::tick_label)
        .y_label_formatter(&teleop_node::plot::tick_label)
        .label_style((FONT, 15))
        .axis_desc_style((FONT, 17))
        .bold_line_style(BLACK.mix(0.2))
        .light_line_style(TRANSPARENT)
        .draw()?;
    Ok(())
}

/// The colour classes in a row, centred in `area`.
fn draw_legend(area: &DrawingArea<BitMapBackend<'_>, Shift>) -> anyhow::Result<()> {
    let style = TextStyle::from((FONT, 18).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
    // (swatch colour, text); the heading has no swatch.
    let entries: Vec<(Option<RGBColor>, &str)> = [(None, "orientations reached:")]
        .into_iter()
        .chain(
            CLASSES
                .iter()
                .map(|(_, colour, label)| (Some(*colour), *label)),
        )
        .chain([(Some(NONE_COLOUR), "none")])
        .collect();
    let (swatch, gap, spacing) = (18i32, 8i32, 32i32);
    let mut widths = Vec::new();
    for (colour, label) in &entries {
        let (w, _) = area.estimate_text_size(label, &style)?;
        let swatch_w = if colour.is_some() { swatch + gap } else { 0 };
        widths.push(swatch_w + i32::try_from(w)?);
    }
    let total = widths.iter().sum::<i32>() + spacing * (i32::try_from(entries.len())? - 1);
    let (w, h) = area.dim_in_pixel();
    let mut x = (i32::try_from(w)? - total) / 2;
    let y = i32::try_from(h)? / 2;
    for ((colour, label), width) in entries.iter().zip(widths) {
        let mut text_x = x;
        if let Some(colour) = colour {
            let corners = [(x, y - swatch / 2), (x + swatch, y + swatch / 2)];
            area.draw(&Rectangle::new(corners, colour.filled()))?;
            area.draw(&Rectangle::new(corners, BLACK.mix(0.5)))?;
            text_x += swatch + gap;
        }
        area.draw(&Text::new(*label, (text_x, y), style.clone()))?;
        x += width + spacing;
    }
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
    write_png(
        &png_path,
        &name.to_uppercase(),
        &grid,
        &counts,
        rotations.len(),
    )?;
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

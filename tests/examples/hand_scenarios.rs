//! Writes the hand-control evidence plots and traces to `docs/img/` (or the directory
//! given as the first argument):
//!
//! * `cup_grasp_force.png` / `.csv`: fingertip contact forces over time while the hand
//!   closes on the cup, one panel per mode (position, fixed impedance, adaptive);
//! * `thumb_load.png` / `.csv`: the screw-pouring stand-in (-0.3 N m on THJ4 from 3 s,
//!   ramped over 2 s) under fixed-gain and adaptive control: THJ4 error and effort.
//!
//! Both in the joint-space world, and again in MuJoCo (`*_mujoco.png` / `.csv`: the cup
//! welded in place, the load MuJoCo's applied torque).
//!
//! `cargo run --release -p teleop-system-tests --example hand_scenarios`

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use plotters::prelude::*;
use teleop_control::hand::{HandControllerConfig, HandMode};
use teleop_hardware::FINGERTIP_COUNT;
use teleop_sim::{ExternalLoad, LoadTarget};
use teleop_system_tests::scenarios::{GraspRun, GraspSample, SimEngine, grasp_run};

/// Control modes: the CSV's name and the plot's title.
const MODES: [(HandMode, &str, &str); 3] = [
    (HandMode::Position, "position", "position control"),
    (
        HandMode::FixedImpedance,
        "fixed_impedance",
        "fixed-gain impedance",
    ),
    (HandMode::Adaptive, "adaptive", "adaptive impedance"),
];
/// Fingertips in `fingertip_force_n` order, with their colours: ff red, mf orange,
/// rf green, lf blue, th purple.
const FINGERS: [(&str, RGBColor); FINGERTIP_COUNT] = [
    ("ff (first)", RGBColor(214, 39, 40)),
    ("mf (middle)", RGBColor(255, 127, 14)),
    ("rf (ring)", RGBColor(44, 160, 44)),
    ("lf (little)", RGBColor(31, 119, 180)),
    ("th (thumb)", RGBColor(148, 103, 189)),
];
/// Torque of the thumb load, N m on THJ4.
const THUMB_LOAD_NM: f64 = -0.3;
/// Time axis of every panel, s.
const T_MAX_S: f64 = 9.0;

fn main() -> anyhow::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("docs/img"), PathBuf::from);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    figures(&dir, SimEngine::JointSpace, "")?;
    figures(&dir, SimEngine::Mujoco, "_mujoco")
}

/// The two figures of `engine`'s world, their files named with `suffix`.
fn figures(dir: &Path, engine: SimEngine, suffix: &str) -> anyhow::Result<()> {
    let world = engine.name();
    let base = GraspRun {
        engine,
        ..GraspRun::default()
    };
    // Cup grasp, no load.
    let mut grasp = Vec::new();
    for (mode, _, _) in MODES {
        let cfg = HandControllerConfig {
            mode,
            ..HandControllerConfig::default()
        };
        grasp.push(grasp_run(&base, &cfg)?);
    }
    let mut csv = String::from("mode,time_s,ff_n,mf_n,rf_n,lf_n,th_n\n");
    for ((_, name, _), run) in MODES.iter().zip(&grasp) {
        for s in run {
            let f = s.fingertip_force_n;
            writeln!(
                csv,
                "{name},{:.3},{:.4},{:.4},{:.4},{:.4},{:.4}",
                s.time_s, f[0], f[1], f[2], f[3], f[4]
            )?;
        }
    }
    write(
        &dir.join(format!("cup_grasp_force{suffix}.csv")),
        csv.as_bytes(),
    )?;
    let y_max = grasp
        .iter()
        .flatten()
        .flat_map(|s| s.fingertip_force_n)
        .fold(1.0, f64::max);
    let panels: Vec<Panel> = MODES
        .iter()
        .zip(&grasp)
        .map(|((_, _, title), run)| Panel {
            title: format!("Cup grasp ({world}), {title}: fingertip contact forces"),
            y_desc: "contact force (N)",
            y_range: (0.0, headroom(y_max)),
            series: FINGERS
                .iter()
                .enumerate()
                .map(|(f, (label, colour))| Series {
                    label: (*label).to_owned(),
                    colour: *colour,
                    points: run
                        .iter()
                        .map(|s| (s.time_s, s.fingertip_force_n[f]))
                        .collect(),
                })
                .collect(),
            marker: None,
        })
        .collect();
    let grasp_png = dir.join(format!("cup_grasp_force{suffix}.png"));
    plot(&grasp_png, &panels)?;

    // Thumb under load.
    let mut load = ExternalLoad::screw_pouring(3.0);
    load.target = LoadTarget::JointTorque {
        joint: "rh_THJ4".into(),
        torque_nm: THUMB_LOAD_NM,
    };
    let load_marker = (
        load.start_s,
        format!(
            "load {THUMB_LOAD_NM} N m on THJ4 from {} s ({} s ramp)",
            load.start_s, load.ramp_s
        ),
    );
    let mut run = base.clone();
    run.cup.loads = vec![load];
    let mut loaded: Vec<Vec<GraspSample>> = Vec::new();
    for mode in [HandMode::FixedImpedance, HandMode::Adaptive] {
        let cfg = HandControllerConfig {
            mode,
            ..HandControllerConfig::default()
        };
        loaded.push(grasp_run(&run, &cfg)?);
    }
    let mut csv = String::from("mode,time_s,thj4_error_rad,thj4_effort_nm,th_force_n\n");
    for (name, r) in ["fixed_impedance", "adaptive"].iter().zip(&loaded) {
        for s in r {
            writeln!(
                csv,
                "{name},{:.3},{:.5},{:.4},{:.4}",
                s.time_s,
                s.joint_rad - s.joint_target_rad,
                s.joint_effort_nm,
                s.fingertip_force_n[4]
            )?;
        }
    }
    write(&dir.join(format!("thumb_load{suffix}.csv")), csv.as_bytes())?;
    // Fixed gain red, adaptive blue.
    let styles = [
        ("fixed-gain impedance", RGBColor(214, 39, 40)),
        ("adaptive impedance", RGBColor(31, 119, 180)),
    ];
    let series = |f: &dyn Fn(&GraspSample) -> f64| -> Vec<Series> {
        loaded
            .iter()
            .zip(styles)
            .map(|(r, (label, colour))| Series {
                label: label.to_owned(),
                colour,
                points: r.iter().map(|s| (s.time_s, f(s))).collect(),
            })
            .collect()
    };
    let err = series(&|s| (s.joint_target_rad - s.joint_rad).abs());
    let effort = series(&|s| s.joint_effort_nm);
    let range_of = |ls: &[Series]| {
        let (lo, hi) = ls
            .iter()
            .flat_map(|l| l.points.iter().map(|p| p.1))
            .fold((0.0, 1e-6), |(lo, hi), v| {
                (f64::min(lo, v), f64::max(hi, v))
            });
        (if lo < 0.0 { -headroom(-lo) } else { 0.0 }, headroom(hi))
    };
    let panels = vec![
        Panel {
            title: format!("Thumb under load ({world}): THJ4 position error"),
            y_desc: "|THJ4 error| (rad)",
            y_range: range_of(&err),
            series: err,
            marker: Some(load_marker.clone()),
        },
        Panel {
            title: format!("Thumb under load ({world}): THJ4 motor effort"),
            y_desc: "THJ4 effort (N m)",
            y_range: range_of(&effort),
            series: effort,
            marker: Some(load_marker),
        },
    ];
    let load_png = dir.join(format!("thumb_load{suffix}.png"));
    plot(&load_png, &panels)?;
    println!(
        "wrote {} and {} (+ .csv)",
        grasp_png.display(),
        load_png.display()
    );
    Ok(())
}

fn write(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

/// The next "nice" axis maximum (1, 1.2, 1.5, 2, 2.5, 3, 4, 5, 6, 8 x 10^k) at or above
/// `x`.
fn nice(x: f64) -> f64 {
    let p = 10f64.powf(x.log10().floor());
    [1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|v| *v >= x)
        .unwrap_or(10.0 * p)
}

/// A nice axis end for data up to `x`, leaving room above the curves for the legend.
fn headroom(x: f64) -> f64 {
    nice(1.6 * x)
}

/// One curve of a panel.
struct Series {
    label: String,
    colour: RGBColor,
    points: Vec<(f64, f64)>,
}

/// One chart: a quantity over time.
struct Panel {
    title: String,
    /// The y axis' name with its unit.
    y_desc: &'static str,
    y_range: (f64, f64),
    series: Vec<Series>,
    /// A moment to mark with a dashed vertical line, s, and its legend entry.
    marker: Option<(f64, String)>,
}

const WIDTH_PX: u32 = 1000;
const PANEL_HEIGHT_PX: u32 = 330;
const FONT: &str = teleop_node::plot::FONT_FAMILY;

/// Stacked panels sharing the time axis `0..T_MAX_S`, each with a title, labelled axes
/// and a legend.
fn plot(path: &Path, panels: &[Panel]) -> anyhow::Result<()> {
    teleop_node::plot::register_fonts()?;
    let rows = u32::try_from(panels.len())?;
    let root = BitMapBackend::new(path, (WIDTH_PX, PANEL_HEIGHT_PX * rows)).into_drawing_area();
    root.fill(&WHITE)?;
    for (area, p) in root.split_evenly((panels.len(), 1)).iter().zip(panels) {
        let (y_min, y_max) = p.y_range;
        let mut chart = ChartBuilder::on(area)
            .caption(&p.title, (FONT, 22))
            .margin(10)
            .margin_right(20)
            .x_label_area_size(48)
            .y_label_area_size(72)
            .build_cartesian_2d(0.0..T_MAX_S, y_min..y_max)?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc(p.y_desc)
            .x_labels(10)
            .y_labels(6)
            .x_label_formatter(&teleop_node::plot::tick_label)
            .y_label_formatter(&teleop_node::plot::tick_label)
            .label_style((FONT, 15))
            .axis_desc_style((FONT, 16))
            .bold_line_style(BLACK.mix(0.15))
            .light_line_style(BLACK.mix(0.05))
            .draw()?;
        if let Some((t, label)) = &p.marker {
            let grey = RGBColor(110, 110, 110).stroke_width(2);
            chart
                .draw_series(DashedLineSeries::new(
                    [(*t, y_min), (*t, y_max)],
                    8,
                    6,
                    grey,
                ))?
                .label(label)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 22, y)], grey));
        }
        for s in &p.series {
            let style = s.colour.stroke_width(2);
            chart
                .draw_series(LineSeries::new(s.points.iter().copied(), style))?
                .label(&s.label)
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 22, y)], style));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT, 15))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK.mix(0.4))
            .draw()?;
    }
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

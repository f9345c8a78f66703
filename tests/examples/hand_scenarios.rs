//! Writes the hand-control evidence plots and traces to `docs/img/` (or the directory
//! given as the first argument):
//!
//! * `cup_grasp_force.png` / `.csv`: fingertip contact forces over time while the hand
//!   closes on the cup, one panel per mode (position, fixed impedance, adaptive);
//! * `thumb_load.png` / `.csv`: the screw-pouring stand-in (-0.3 N m on THJ4 from 3 s,
//!   ramped over 2 s) under fixed-gain and adaptive control: THJ4 error and effort.
//!
//! `cargo run --release -p teleop-remote-site --example hand_scenarios`

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use teleop_control::hand::{HandControllerConfig, HandMode};
use teleop_hardware::FINGERTIPS;
use teleop_sim::{ExternalLoad, LoadTarget};
use teleop_system_tests::scenarios::{GraspRun, GraspSample, grasp_run};

const MODES: [(HandMode, &str); 3] = [
    (HandMode::Position, "position"),
    (HandMode::FixedImpedance, "fixed_impedance"),
    (HandMode::Adaptive, "adaptive"),
];
/// Fingertip colours: ff red, mf orange, rf green, lf blue, th purple.
const FINGER_COLOURS: [[u8; 3]; 5] = [
    [214, 39, 40],
    [255, 127, 14],
    [44, 160, 44],
    [31, 119, 180],
    [148, 103, 189],
];

fn main() -> anyhow::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("docs/img"), PathBuf::from);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;

    // Cup grasp, no load.
    let mut grasp = Vec::new();
    for (mode, _) in MODES {
        let cfg = HandControllerConfig {
            mode,
            ..HandControllerConfig::default()
        };
        grasp.push(grasp_run(&GraspRun::default(), &cfg)?);
    }
    let mut csv = String::from("mode,time_s,ff_n,mf_n,rf_n,lf_n,th_n\n");
    for ((_, name), run) in MODES.iter().zip(&grasp) {
        for s in run {
            let f = s.fingertip_force_n;
            writeln!(
                csv,
                "{name},{:.3},{:.4},{:.4},{:.4},{:.4},{:.4}",
                s.time_s, f[0], f[1], f[2], f[3], f[4]
            )?;
        }
    }
    write(&dir.join("cup_grasp_force.csv"), csv.as_bytes())?;
    let y_max = grasp
        .iter()
        .flatten()
        .flat_map(|s| s.fingertip_force_n)
        .fold(1.0, f64::max);
    let panels: Vec<Panel> = grasp
        .iter()
        .map(|run| Panel {
            y_max: nice(y_max),
            y_min: 0.0,
            lines: (0..5)
                .map(|f| Line {
                    colour: FINGER_COLOURS[f],
                    points: run
                        .iter()
                        .map(|s| (s.time_s, s.fingertip_force_n[f]))
                        .collect(),
                })
                .collect(),
        })
        .collect();
    let grasp_png = dir.join("cup_grasp_force.png");
    plot(&grasp_png, 9.0, &panels)?;

    // Thumb under load.
    let mut load = ExternalLoad::screw_pouring(3.0);
    load.target = LoadTarget::JointTorque {
        joint: "rh_THJ4".into(),
        torque_nm: -0.3,
    };
    let mut run = GraspRun::default();
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
    write(&dir.join("thumb_load.csv"), csv.as_bytes())?;
    let colours = [[214, 39, 40], [31, 119, 180]]; // fixed red, adaptive blue
    let series = |f: &dyn Fn(&GraspSample) -> f64| -> Vec<Line> {
        loaded
            .iter()
            .zip(colours)
            .map(|(r, colour)| Line {
                colour,
                points: r.iter().map(|s| (s.time_s, f(s))).collect(),
            })
            .collect()
    };
    let err = series(&|s| (s.joint_target_rad - s.joint_rad).abs());
    let effort = series(&|s| s.joint_effort_nm);
    let max_of = |ls: &[Line]| {
        ls.iter()
            .flat_map(|l| l.points.iter().map(|p| p.1))
            .fold(1e-6, f64::max)
    };
    let panels = vec![
        Panel {
            y_min: 0.0,
            y_max: nice(max_of(&err)),
            lines: err,
        },
        Panel {
            y_min: 0.0,
            y_max: nice(max_of(&effort)),
            lines: effort,
        },
    ];
    let load_png = dir.join("thumb_load.png");
    plot(&load_png, 9.0, &panels)?;
    println!(
        "wrote {} and {} (+ .csv); fingertip colours {:?} = red, orange, green, blue, purple",
        grasp_png.display(),
        load_png.display(),
        FINGERTIPS
    );
    Ok(())
}

fn write(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

/// The next "nice" axis maximum (1, 2, 2.5, 5 x 10^k) at or above `x`.
fn nice(x: f64) -> f64 {
    let p = 10f64.powf(x.log10().floor());
    [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * p)
        .find(|v| *v >= x)
        .unwrap_or(10.0 * p)
}

struct Line {
    colour: [u8; 3],
    points: Vec<(f64, f64)>,
}

struct Panel {
    y_min: f64,
    y_max: f64,
    lines: Vec<Line>,
}

const W: usize = 900;
const PANEL_H: usize = 220;
const LEFT: usize = 60;
const RIGHT: usize = 20;
const TOP: usize = 12;
const BOTTOM: usize = 24;

struct Canvas {
    w: usize,
    h: usize,
    rgb: Vec<u8>,
}

impl Canvas {
    fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as usize) < self.w && (y as usize) < self.h {
            let i = 3 * (y as usize * self.w + x as usize);
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: [u8; 3]) {
        let n = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as usize).max(1);
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let (x, y) = (x0 + t * (x1 - x0), y0 + t * (y1 - y0));
            // 2 px thick.
            self.set(x.round() as i64, y.round() as i64, c);
            self.set(x.round() as i64, y.round() as i64 + 1, c);
        }
    }

    /// Digits, '.', '-' in a 3x5 font scaled by 2.
    fn text(&mut self, x: i64, y: i64, s: &str, c: [u8; 3]) {
        for (k, ch) in s.chars().enumerate() {
            let glyph: [u8; 5] = match ch {
                '0' => [7, 5, 5, 5, 7],
                '1' => [2, 6, 2, 2, 7],
                '2' => [7, 1, 7, 4, 7],
                '3' => [7, 1, 7, 1, 7],
                '4' => [5, 5, 7, 1, 1],
                '5' => [7, 4, 7, 1, 7],
                '6' => [7, 4, 7, 5, 7],
                '7' => [7, 1, 1, 1, 1],
                '8' => [7, 5, 7, 5, 7],
                '9' => [7, 5, 7, 1, 7],
                '.' => [0, 0, 0, 0, 2],
                '-' => [0, 0, 7, 0, 0],
                _ => [0; 5],
            };
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            self.set(x + 8 * k as i64 + 2 * col + dx, y + 2 * row as i64 + dy, c);
                        }
                    }
                }
            }
        }
    }
}

fn label(v: f64) -> String {
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// Stacked panels sharing the time axis `0..t_max` s; grid lines every second and at
/// quarters of each panel's y range, labelled.
fn plot(path: &Path, t_max: f64, panels: &[Panel]) -> anyhow::Result<()> {
    let ph = TOP + PANEL_H + BOTTOM;
    let mut c = Canvas {
        w: W,
        h: ph * panels.len(),
        rgb: vec![255; 3 * W * ph * panels.len()],
    };
    let (grid, axis, ink) = ([225, 225, 225], [90, 90, 90], [40, 40, 40]);
    let pw = (W - LEFT - RIGHT) as f64;
    for (k, p) in panels.iter().enumerate() {
        let y0 = (k * ph + TOP) as f64;
        let to_px = |t: f64, v: f64| {
            let fx = (t / t_max).clamp(0.0, 1.0);
            let fy = ((v - p.y_min) / (p.y_max - p.y_min)).clamp(0.0, 1.0);
            (LEFT as f64 + fx * pw, y0 + (1.0 - fy) * PANEL_H as f64)
        };
        for s in 0..=(t_max as usize) {
            let (x, _) = to_px(s as f64, 0.0);
            c.line((x, y0), (x, y0 + PANEL_H as f64), grid);
            c.text(
                x as i64 - 3,
                (y0 + PANEL_H as f64) as i64 + 6,
                &s.to_string(),
                ink,
            );
        }
        for q in 0..=4 {
            let v = p.y_min + (p.y_max - p.y_min) * f64::from(q) / 4.0;
            let (_, y) = to_px(0.0, v);
            c.line((LEFT as f64, y), (LEFT as f64 + pw, y), grid);
            let l = label(v);
            c.text(LEFT as i64 - 8 - 8 * l.len() as i64, y as i64 - 5, &l, ink);
        }
        c.line((LEFT as f64, y0), (LEFT as f64, y0 + PANEL_H as f64), axis);
        c.line(
            (LEFT as f64, y0 + PANEL_H as f64),
            (LEFT as f64 + pw, y0 + PANEL_H as f64),
            axis,
        );
        for l in &p.lines {
            for w in l.points.windows(2) {
                c.line(to_px(w[0].0, w[0].1), to_px(w[1].0, w[1].1), l.colour);
            }
        }
    }
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), W as u32, c.h as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()?.write_image_data(&c.rgb)?;
    Ok(())
}

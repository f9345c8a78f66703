//! Evaluation of the hand networks with the thesis's metrics, on datasets written by
//! `hand_dataset` or generated in memory, through the same [`HandEstimator`] the
//! run-time node uses; the report format; the fraction-of-frames plot.

use std::path::Path;

use serde::{Deserialize, Serialize};
use teleop_hand_dataset::{Generator, GeneratorConfig, Loaded};
use teleop_hand_inference::metrics::{Accumulator, Summary, THRESHOLDS_RAD};
use teleop_hand_inference::{HandEstimate, HandEstimator, InferenceError, JointModel};
use teleop_hand_model::retarget::SHADOW_FINGER_DOF;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;

/// The committed model, relative to the workspace root.
pub const COMMITTED_MODEL: &str = "local_site/models/hand/model.onnx";
/// Its evaluation report, relative to the workspace root.
pub const COMMITTED_REPORT: &str = "local_site/models/hand/report.json";

/// Errors of an evaluation.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error(transparent)]
    Inference(#[from] InferenceError),
    #[error(transparent)]
    Dataset(#[from] teleop_hand_dataset::DatasetError),
    #[error(transparent)]
    Model(#[from] teleop_hand_model::HandModelError),
}

/// One model on one dataset, as written in reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub model: String,
    pub dataset: String,
    pub frames: usize,
    pub no_hand: usize,
    /// Fraction of frames with max joint error <= 0.1 / 0.15 / 0.2 / 0.25 rad.
    pub fraction_within: [f64; 4],
    pub mean_error_rad: f64,
    pub per_joint_rad: Vec<f64>,
    pub tip_mean_mm: f64,
    pub tip_p90_mm: f64,
}

impl Row {
    /// A row from a summary.
    #[must_use]
    pub fn new(model: &str, dataset: &str, s: &Summary) -> Self {
        Self {
            model: model.to_owned(),
            dataset: dataset.to_owned(),
            frames: s.frames,
            no_hand: s.no_hand,
            fraction_within: s.fraction_within,
            mean_error_rad: s.mean_error_rad,
            per_joint_rad: s.per_joint_rad.to_vec(),
            tip_mean_mm: s.tip_mean_mm,
            tip_p90_mm: s.tip_p90_mm,
        }
    }
}

/// The evaluation report of a set of models (written next to the committed model).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// The command that produced the report.
    pub command: String,
    pub thresholds_rad: [f64; 4],
    pub joint_names: Vec<String>,
    pub rows: Vec<Row>,
    /// What the CI test of the committed model asserts on a freshly generated seeded
    /// test set (slightly below the measured values: the CI set is smaller).
    pub ci: CiThresholds,
}

/// Bounds the CI test asserts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CiThresholds {
    /// Pairs generated for the check, and their seed.
    pub frames: usize,
    pub seed: u64,
    /// At least this fraction of frames with max joint error <= 0.1 rad.
    pub min_fraction_within_0_1: f64,
    /// At least this fraction with max joint error <= 0.2 rad.
    pub min_fraction_within_0_2: f64,
    /// At most this mean joint error (rad).
    pub max_mean_error_rad: f64,
}

/// Runs `estimator` on every pair of a loaded dataset.
///
/// # Errors
/// [`EvalError::Inference`] if the model fails on a frame.
pub fn evaluate_loaded<M: JointModel>(
    estimator: &mut HandEstimator<M>,
    data: &Loaded,
) -> Result<Accumulator, EvalError> {
    let mut acc = Accumulator::new()?;
    let n = data.manifest.image_size * data.manifest.image_size;
    for i in 0..data.count {
        let input = &data.human[i * n..(i + 1) * n];
        let mut truth = [0.0; SHADOW_FINGER_DOF];
        for (k, t) in truth.iter_mut().enumerate() {
            *t = f64::from(data.joints[i * SHADOW_FINGER_DOF + k]);
        }
        add(&mut acc, estimator.estimate_preprocessed(input)?, &truth);
    }
    Ok(acc)
}

/// Generates `count` pairs of `config` in memory and runs `estimator` on them.
///
/// # Errors
/// As [`evaluate_loaded`], plus generation errors.
pub fn evaluate_generated<M: JointModel>(
    estimator: &mut HandEstimator<M>,
    config: GeneratorConfig,
    count: usize,
) -> Result<Accumulator, EvalError> {
    let mut generator = Generator::new(config)?;
    let mut acc = Accumulator::new()?;
    for i in 0..count {
        let s = generator.sample(i as u64)?;
        let truth = s.joints.map(f64::from);
        add(&mut acc, estimator.estimate_preprocessed(&s.human)?, &truth);
    }
    Ok(acc)
}

fn add(acc: &mut Accumulator, estimate: HandEstimate, truth: &[f64; SHADOW_FINGER_DOF]) {
    match estimate {
        HandEstimate::Hand { joints, .. } => acc.add(Some(&joints), truth),
        HandEstimate::NoHand { .. } => acc.add(None, truth),
    }
}

/// A markdown table of rows like thesis Table 5.1.
#[must_use]
pub fn markdown_table(rows: &[Row]) -> String {
    let mut s = String::from(
        "| model | test set | frames | max err <= 0.1 rad | <= 0.15 | <= 0.2 | <= 0.25 | mean err (rad) | fingertip mean / p90 (mm) |\n|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {} | {} | {:.1} % | {:.1} % | {:.1} % | {:.1} % | {:.4} | {:.1} / {:.1} |\n",
            r.model,
            r.dataset,
            r.frames,
            100.0 * r.fraction_within[0],
            100.0 * r.fraction_within[1],
            100.0 * r.fraction_within[2],
            100.0 * r.fraction_within[3],
            r.mean_error_rad,
            r.tip_mean_mm,
            r.tip_p90_mm
        );
    }
    s
}

/// A markdown table of the mean error per joint, one column per row given.
#[must_use]
pub fn per_joint_table(rows: &[Row]) -> String {
    let mut s = String::from("| joint |");
    for r in rows {
        s += &format!(" {} |", r.model);
    }
    s += "\n|---|";
    s += &"---|".repeat(rows.len());
    s += "\n";
    for (j, name) in SHADOW_FINGER_JOINTS.iter().enumerate() {
        s += &format!("| {name} |");
        for r in rows {
            s += &format!(
                " {:.3} |",
                r.per_joint_rad.get(j).copied().unwrap_or(f64::NAN)
            );
        }
        s += "\n";
    }
    s
}

/// Draws the fraction-of-frames curves (thesis Fig. 5.x style): x = max joint error
/// threshold (rad), y = fraction of frames within it (%).
///
/// # Errors
/// Font or drawing errors as text.
pub fn plot_curves(
    path: &Path,
    title: &str,
    curves: &[(String, Vec<(f64, f64)>)],
) -> Result<(), String> {
    use plotters::prelude::*;
    teleop_node::plot::register_fonts().map_err(|e| e.to_string())?;
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let max_x = curves
        .iter()
        .flat_map(|(_, c)| c.iter().map(|p| p.0))
        .fold(0.0_f64, f64::max)
        .max(0.05);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 24))
        .margin(15)
        .x_label_area_size(50)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..max_x, 0.0..100.0)
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc("maximum joint error threshold (rad)")
        .y_desc("frames within the threshold (%)")
        .x_label_formatter(&teleop_node::plot::tick_label)
        .y_label_formatter(&teleop_node::plot::tick_label)
        .draw()
        .map_err(|e| e.to_string())?;
    for (i, (label, points)) in curves.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        chart
            .draw_series(LineSeries::new(
                points.iter().map(|(x, y)| (*x, 100.0 * y)),
                color.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?
            .label(label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

/// The thresholds of the fraction table.
#[must_use]
pub fn thresholds() -> [f64; 4] {
    THRESHOLDS_RAD
}

/// Draws `pairs` dataset examples side by side (human crop above, Shadow crop below,
/// depth in the cube's normalised units as colour, a colour scale on the right).
///
/// # Errors
/// Font or drawing errors as text.
pub fn plot_pairs(path: &Path, data: &Loaded, indices: &[usize]) -> Result<(), String> {
    use plotters::prelude::*;
    teleop_node::plot::register_fonts().map_err(|e| e.to_string())?;
    let s = data.manifest.image_size;
    let cols = indices.len().max(1);
    let cell = 200u32;
    let root =
        BitMapBackend::new(path, (cell * cols as u32 + 120, 2 * cell + 90)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let titled = root
        .titled(
            "Paired 96 x 96 crops (axes in pixels): human (top, noisy), Shadow (bottom), same camera-to-palm transform",
            ("sans-serif", 16),
        )
        .map_err(|e| e.to_string())?;
    let (grid, scale) = titled.split_horizontally(cell * cols as u32 + 10);
    let colour = |v: f32| -> RGBColor {
        if v >= 1.0 {
            return RGBColor(235, 235, 235);
        }
        // Viridis, five anchors, linear between them.
        const ANCHORS: [(f64, f64, f64); 5] = [
            (68.0, 1.0, 84.0),
            (59.0, 82.0, 139.0),
            (33.0, 145.0, 140.0),
            (94.0, 201.0, 98.0),
            (253.0, 231.0, 37.0),
        ];
        let t = f64::from((v + 1.0) / 2.0).clamp(0.0, 1.0) * 4.0;
        let i = (t.floor() as usize).min(3);
        let f = t - i as f64;
        let (a, b) = (ANCHORS[i], ANCHORS[i + 1]);
        let mix = |x: f64, y: f64| (x + f * (y - x)).round() as u8;
        RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
    };
    let panels = grid.split_evenly((2, cols));
    for (row, images) in [(0usize, &data.human), (1, &data.robot)] {
        for (c, idx) in indices.iter().enumerate() {
            let panel = &panels[row * cols + c];
            let meta = &data.meta[idx * teleop_hand_dataset::META_COLUMNS.len()..];
            let caption = if row == 0 {
                format!("human, {:.2} m, {:.0} deg off-axis", meta[0], meta[1])
            } else {
                "Shadow (label)".to_owned()
            };
            let mut chart = ChartBuilder::on(panel)
                .caption(caption, ("sans-serif", 12))
                .margin(4)
                .x_label_area_size(18)
                .y_label_area_size(24)
                .build_cartesian_2d(0..s as i32, s as i32..0)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_labels(3)
                .y_labels(3)
                .label_style(("sans-serif", 10))
                .draw()
                .map_err(|e| e.to_string())?;
            let img = &images[idx * s * s..(idx + 1) * s * s];
            chart
                .draw_series((0..s * s).map(|i| {
                    let (x, y) = ((i % s) as i32, (i / s) as i32);
                    Rectangle::new([(x, y), (x + 1, y + 1)], colour(img[i]).filled())
                }))
                .map_err(|e| e.to_string())?;
        }
    }
    // Colour scale: normalised depth -1 (near) .. 1 (far), in mm from the cube centre.
    let mut bar = ChartBuilder::on(&scale)
        .caption("depth (mm)", ("sans-serif", 12))
        .margin(10)
        .y_label_area_size(40)
        .build_cartesian_2d(0..1, -125.0..125.0)
        .map_err(|e| e.to_string())?;
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_desc("from the cube centre")
        .label_style(("sans-serif", 10))
        .draw()
        .map_err(|e| e.to_string())?;
    bar.draw_series((0..100).map(|i| {
        let v = -125.0 + 2.5 * f64::from(i);
        Rectangle::new([(0, v), (1, v + 2.5)], colour((v / 125.0) as f32).filled())
    }))
    .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

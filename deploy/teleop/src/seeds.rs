//! `teleop launch --task T --seeds N`: a task run N times, each on a seed of its own
//! (the robot world's object and model mismatch, the operator site's world, the WAN's
//! draws), judged per run by the robot-site simulator from ground truth, and summed
//! up as the thesis reports its tasks: success rate and mean completion time (with the
//! 90th percentile), next to the thesis's own figures for the task.
//!
//! Writes `summary.json` and `summary.png` beside the runs' own reports (`seed-S/`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::report::{JobOutcome, OperatorOutcome};
use crate::tasks::{ThesisFigure, thesis_figures};

/// One seeded run.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SeedRun {
    pub seed: u64,
    /// The job as the simulator judged it (`None`: it gave no verdict).
    pub job: Option<JobOutcome>,
    /// What the watching operator did and saw.
    pub operator: Option<OperatorOutcome>,
    /// Why the run itself failed (a node exited early, did not stop), if it did.
    pub error: Option<String>,
    /// Where its own report is.
    pub report_dir: PathBuf,
}

impl SeedRun {
    fn succeeded(&self) -> bool {
        self.job.as_ref().is_some_and(|j| j.succeeded)
    }

    /// Why it did not succeed, or how long it took.
    fn describe(&self) -> String {
        let mut s = match &self.job {
            Some(j) => j.describe(),
            None => "no verdict from the simulator".to_owned(),
        };
        if let Some(o) = &self.operator {
            let _ = write!(s, "; operator: {}", o.describe());
        }
        if let Some(e) = &self.error {
            let _ = write!(s, "; run error: {e}");
        }
        s
    }
}

/// Our figures against one of the thesis's.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Comparison {
    pub thesis: ThesisFigure,
    /// Success rate at or above the thesis's.
    pub success_met: bool,
    /// Mean completion time at or below the thesis's (`None`: no run succeeded).
    pub time_met: Option<bool>,
}

/// The runs summed up.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SeedsSummary {
    pub task: String,
    /// The emulated WAN, if the runs had one (`teleop launch --wan`).
    pub wan: Option<String>,
    /// The WAN's round trip, ms (0 without one).
    pub round_trip_ms: f64,
    /// TCP segments the WAN loses, each way, % (0 without one).
    pub loss_pct: f64,
    /// The WAN's bandwidth cap, each way, Mbit/s (`None`: uncapped, or no WAN).
    pub rate_mbit: Option<f64>,
    pub runs: Vec<SeedRun>,
    pub succeeded: usize,
    pub success_pct: f64,
    /// Over the successful runs, s.
    pub completion_mean_s: Option<f64>,
    /// Nearest-rank 90th percentile over the successful runs, s.
    pub completion_p90_s: Option<f64>,
    pub thesis: Vec<Comparison>,
}

impl SeedsSummary {
    #[must_use]
    pub fn new(task: &str, wan: Option<&teleop_wan_link::Impairment>, runs: Vec<SeedRun>) -> Self {
        let mut times: Vec<f64> = runs
            .iter()
            .filter(|r| r.succeeded())
            .filter_map(|r| r.job.as_ref()?.completion_s)
            .filter(|t| t.is_finite())
            .collect();
        times.sort_by(f64::total_cmp);
        let succeeded = runs.iter().filter(|r| r.succeeded()).count();
        let success_pct = if runs.is_empty() {
            0.0
        } else {
            100.0 * succeeded as f64 / runs.len() as f64
        };
        let completion_mean_s =
            (!times.is_empty()).then(|| times.iter().sum::<f64>() / times.len() as f64);
        // Nearest rank: the smallest time with at least 90 % of the times at or below.
        let completion_p90_s = (!times.is_empty()).then(|| {
            let rank = (0.9 * times.len() as f64).ceil() as usize;
            times[rank.clamp(1, times.len()) - 1]
        });
        let thesis = thesis_figures(task)
            .iter()
            .map(|&f| Comparison {
                thesis: f,
                success_met: !runs.is_empty() && success_pct >= f.success_pct,
                time_met: completion_mean_s.map(|t| t <= f.time_s),
            })
            .collect();
        Self {
            task: task.to_owned(),
            wan: wan.map(crate::site_link::describe),
            round_trip_ms: wan.map_or(0.0, |w| 2.0 * w.delay_ms),
            loss_pct: wan.map_or(0.0, |w| 100.0 * w.loss),
            rate_mbit: wan.and_then(|w| w.rate_mbit),
            runs,
            succeeded,
            success_pct,
            completion_mean_s,
            completion_p90_s,
            thesis,
        }
    }

    #[must_use]
    pub fn text(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "== teleop launch --seeds: task {}, {} runs, {}",
            self.task,
            self.runs.len(),
            self.wan
                .as_deref()
                .unwrap_or("no WAN (both sites on loopback, peer to peer)")
        );
        for r in &self.runs {
            let _ = writeln!(s, "  seed {:<6} {}", r.seed, r.describe());
        }
        let fmt = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |t| format!("{t:.1} s"));
        let _ = writeln!(
            s,
            "success {}/{} ({:.0} %), completion time over the successes: mean {}, p90 {}",
            self.succeeded,
            self.runs.len(),
            self.success_pct,
            fmt(self.completion_mean_s),
            fmt(self.completion_p90_s)
        );
        for c in &self.thesis {
            let verdict = |met: Option<bool>| match met {
                Some(true) => "met",
                Some(false) => "MISSED",
                None => "not judged",
            };
            let _ = writeln!(
                s,
                "  thesis {}: {:.0} % in {:.1} s; success rate {}, time {}",
                c.thesis.source,
                c.thesis.success_pct,
                c.thesis.time_s,
                verdict(Some(c.success_met)),
                verdict(c.time_met)
            );
        }
        s
    }

    /// `summary.json` and `summary.png` into `dir`.
    ///
    /// # Errors
    /// Creating or writing the files.
    pub fn write_files(&self, dir: &Path) -> anyhow::Result<()> {
        use anyhow::Context;
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let json = dir.join("summary.json");
        std::fs::write(&json, serde_json::to_string_pretty(self)?)
            .with_context(|| format!("writing {}", json.display()))?;
        let png = dir.join("summary.png");
        match self.write_png(&png) {
            Ok(()) => println!(
                "summary written to {} and {}",
                json.display(),
                png.display()
            ),
            Err(e) => println!("summary written to {}; no plot: {e}", json.display()),
        }
        Ok(())
    }

    /// Completion time per seed (failures marked at the top), the mean, and the
    /// thesis's times; the success rates beside the thesis's in the title.
    fn write_png(&self, path: &Path) -> anyhow::Result<()> {
        use plotters::prelude::*;
        let e = |e: &dyn std::fmt::Display| anyhow::anyhow!("{e}");
        teleop_node::plot::register_fonts()?;
        let root = BitMapBackend::new(path, (1200, 700)).into_drawing_area();
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let thesis = self
            .thesis
            .iter()
            .map(|c| format!("{:.0} %", c.thesis.success_pct))
            .collect::<Vec<_>>()
            .join(" / ");
        let title = format!(
            "{}: {}/{} runs succeeded ({:.0} %; thesis {}), round trip {:.0} ms",
            self.task,
            self.succeeded,
            self.runs.len(),
            self.success_pct,
            if thesis.is_empty() { "-" } else { &thesis },
            self.round_trip_ms
        );
        let longest = self
            .runs
            .iter()
            .filter_map(|r| r.job.as_ref()?.completion_s)
            .chain(self.thesis.iter().map(|c| c.thesis.time_s))
            .fold(10.0_f64, f64::max);
        let y_max = longest * 1.25;
        let n = self.runs.len().max(1);
        let mut chart = ChartBuilder::on(&root)
            .caption(&title, ("sans-serif", 24))
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5..(n as f64 - 0.5), 0.0..y_max)
            .map_err(|x| e(&x))?;
        let seeds: Vec<u64> = self.runs.iter().map(|r| r.seed).collect();
        chart
            .configure_mesh()
            .x_desc("run (seed)")
            .y_desc("completion time (s)")
            .x_labels(n.min(20))
            .x_label_formatter(&|x| {
                let i = x.round();
                if (x - i).abs() < 1e-6 && i >= 0.0 {
                    seeds
                        .get(i as usize)
                        .map_or_else(String::new, u64::to_string)
                } else {
                    String::new()
                }
            })
            .y_label_formatter(&teleop_node::plot::tick_label)
            .draw()
            .map_err(|x| e(&x))?;
        let ok: Vec<(f64, f64)> = self
            .runs
            .iter()
            .enumerate()
            .filter(|(_, r)| r.succeeded())
            .filter_map(|(i, r)| Some((i as f64, r.job.as_ref()?.completion_s?)))
            .collect();
        chart
            .draw_series(ok.iter().map(|&(x, t)| {
                Rectangle::new([(x - 0.3, 0.0), (x + 0.3, t)], GREEN.mix(0.7).filled())
            }))
            .map_err(|x| e(&x))?
            .label("succeeded: completion time")
            .legend(|(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], GREEN.filled()));
        let failed: Vec<f64> = self
            .runs
            .iter()
            .enumerate()
            .filter(|(_, r)| !r.succeeded())
            .map(|(i, _)| i as f64)
            .collect();
        chart
            .draw_series(
                failed
                    .iter()
                    .map(|&x| Cross::new((x, y_max * 0.95), 10, RED.stroke_width(3))),
            )
            .map_err(|x| e(&x))?
            .label("failed (no completion time)")
            .legend(|(x, y)| Cross::new((x + 7, y), 6, RED.stroke_width(3)));
        let hline = |t: f64| vec![(-0.5, t), (n as f64 - 0.5, t)];
        if let Some(mean) = self.completion_mean_s {
            chart
                .draw_series(LineSeries::new(hline(mean), BLACK.stroke_width(2)))
                .map_err(|x| e(&x))?
                .label(format!("mean over the successes: {mean:.1} s"))
                .legend(|(x, y)| PathElement::new([(x, y), (x + 14, y)], BLACK.stroke_width(2)));
        }
        let figures: Vec<ThesisFigure> = self.thesis.iter().map(|c| c.thesis).collect();
        thesis_lines(&mut chart, &figures, (-0.5, n as f64 - 0.5), |f| {
            (f.time_s, format!("{:.1} s", f.time_s))
        })?;
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))?;
        Ok(())
    }
}

/// A chart of this module: f64 against f64, drawn into a bitmap.
type Chart<'a, 'b> = plotters::chart::ChartContext<
    'a,
    plotters::backend::BitMapBackend<'b>,
    plotters::coord::cartesian::Cartesian2d<
        plotters::coord::types::RangedCoordf64,
        plotters::coord::types::RangedCoordf64,
    >,
>;

/// The thesis's figures as dashed horizontal lines from `x0` to `x1`, each at the
/// value `value` picks, labelled `thesis SOURCE: <label>`.
fn thesis_lines(
    chart: &mut Chart<'_, '_>,
    thesis: &[ThesisFigure],
    x: (f64, f64),
    value: impl Fn(&ThesisFigure) -> (f64, String),
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    for (f, colour) in thesis.iter().zip([BLUE, MAGENTA, CYAN]) {
        let (y, label) = value(f);
        dashed_line(
            chart,
            x,
            y,
            colour,
            10,
            format!("thesis {}: {label}", f.source),
        )?;
    }
    Ok(())
}

/// A dashed horizontal line at `y` across `x` (dashes `dash` px long), in the legend
/// as `label`.
fn dashed_line(
    chart: &mut Chart<'_, '_>,
    (x0, x1): (f64, f64),
    y: f64,
    colour: plotters::style::RGBColor,
    dash: u32,
    label: String,
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    chart
        .draw_series(DashedLineSeries::new(
            [(x0, y), (x1, y)],
            dash,
            6.min(dash),
            colour.stroke_width(2),
        ))
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .label(label)
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 14, y)], colour.stroke_width(2)));
    Ok(())
}

/// `teleop seeds-plot`: several `--seeds` summaries (one per WAN condition) as a
/// table and a picture of success rate and completion time against the round trip,
/// the loss or the bandwidth cap (`--against`).
#[derive(Debug, Clone, clap::Args)]
pub struct SeedsPlotArgs {
    /// Directories holding a `summary.json` of `teleop launch --seeds` each.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// The picture to write.
    #[arg(long, default_value = "success-vs-round-trip.png")]
    pub out: PathBuf,
    /// The x axis: the WAN setting the summaries differ in.
    #[arg(long, value_enum, default_value_t = Against::RoundTrip)]
    pub against: Against,
}

/// The WAN setting a picture of `seeds-plot` is drawn against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Against {
    /// The round trip between the sites, ms.
    RoundTrip,
    /// The loss of TCP segments, each way, % (none: 0).
    Loss,
    /// The bandwidth cap, each way, Mbit/s; a summary without a cap is drawn as the
    /// uncapped reference.
    Rate,
}

impl Against {
    /// The x axis's description.
    fn axis(self) -> &'static str {
        match self {
            Self::RoundTrip => "round trip between the sites (ms)",
            Self::Loss => "TCP segments lost, each way (%)",
            Self::Rate => "bandwidth cap, each way (Mbit/s)",
        }
    }

    /// The column's header.
    fn header(self) -> &'static str {
        match self {
            Self::RoundTrip => "round trip (ms)",
            Self::Loss => "loss each way (%)",
            Self::Rate => "cap each way (Mbit/s)",
        }
    }

    /// What the title says the picture is against.
    fn title(self) -> &'static str {
        match self {
            Self::RoundTrip => "the WAN's round trip",
            Self::Loss => "the WAN's loss",
            Self::Rate => "the WAN's bandwidth cap",
        }
    }

    /// The condition's place on the axis (`None`: uncapped, for [`Against::Rate`]).
    fn x(self, c: &Condition) -> Option<f64> {
        match self {
            Self::RoundTrip => Some(c.round_trip_ms),
            Self::Loss => Some(c.loss_pct),
            Self::Rate => c.rate_mbit,
        }
    }
}

/// What the picture takes from one summary.
#[derive(Debug, Clone, serde::Deserialize)]
struct Condition {
    task: String,
    #[serde(default)]
    wan: Option<String>,
    round_trip_ms: f64,
    /// Absent from summaries written before it was: no loss.
    #[serde(default)]
    loss_pct: f64,
    #[serde(default)]
    rate_mbit: Option<f64>,
    success_pct: f64,
    succeeded: usize,
    runs: Vec<serde_json::Value>,
    completion_mean_s: Option<f64>,
    completion_p90_s: Option<f64>,
}

/// Reads the summaries, prints a Markdown table sorted by the chosen WAN setting
/// (`--against`), draws the picture.
///
/// # Errors
/// A missing or unreadable summary, summaries of different tasks, two summaries at
/// the same place on the axis, the picture.
pub fn plot(args: &SeedsPlotArgs) -> anyhow::Result<()> {
    use anyhow::Context;
    let mut conditions = Vec::new();
    for dir in &args.dirs {
        let path = dir.join("summary.json");
        let text = std::fs::read_to_string(&path).with_context(|| {
            format!(
                "reading {} (teleop launch --seeds writes it)",
                path.display()
            )
        })?;
        let c: Condition = serde_json::from_str(&text)
            .with_context(|| format!("{} is not a --seeds summary", path.display()))?;
        if ![
            c.round_trip_ms,
            c.loss_pct,
            c.success_pct,
            c.rate_mbit.unwrap_or(1.0),
        ]
        .iter()
        .all(|v| v.is_finite())
        {
            anyhow::bail!(
                "{}: round trip, loss, cap or success rate not a number",
                path.display()
            );
        }
        conditions.push(c);
    }
    let task = conditions[0].task.clone();
    if let Some(other) = conditions.iter().find(|c| c.task != task) {
        anyhow::bail!(
            "the summaries are of different tasks ({task}, {}): one picture per task",
            other.task
        );
    }
    let mut placed: Vec<(Option<f64>, Condition)> = conditions
        .into_iter()
        .map(|c| (args.against.x(&c), c))
        .collect();
    // Uncapped first, then by the setting.
    placed.sort_by(|a, b| match (a.0, b.0) {
        (Some(x), Some(y)) => x.total_cmp(&y),
        (None, Some(_)) => std::cmp::Ordering::Less,
        (Some(_), None) => std::cmp::Ordering::Greater,
        (None, None) => std::cmp::Ordering::Equal,
    });
    if let Some(w) = placed.windows(2).find(|w| w[0].0 == w[1].0) {
        anyhow::bail!(
            "two summaries at the same {} ({:?} and {:?}): one point each",
            args.against.header(),
            w[0].1.wan,
            w[1].1.wan
        );
    }
    let fmt = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |t| format!("{t:.1}"));
    println!(
        "| {} | WAN | runs | succeeded | success rate | completion mean (s) | p90 (s) |",
        args.against.header()
    );
    println!("|---|---|---|---|---|---|---|");
    for (x, c) in &placed {
        println!(
            "| {} | {} | {} | {} | {:.0} % | {} | {} |",
            x.map_or_else(|| "none".to_owned(), |v| format!("{v}")),
            c.wan.as_deref().unwrap_or("none"),
            c.runs.len(),
            c.succeeded,
            c.success_pct,
            fmt(c.completion_mean_s),
            fmt(c.completion_p90_s)
        );
    }
    draw_against(&task, args.against, &placed, &args.out)?;
    println!("picture written to {}", args.out.display());
    Ok(())
}

/// Success and completion time against one WAN setting; for [`Against::Rate`], the
/// uncapped summary (if any) drawn as dashed reference lines.
fn draw_against(
    task: &str,
    against: Against,
    placed: &[(Option<f64>, Condition)],
    path: &Path,
) -> anyhow::Result<()> {
    use plotters::prelude::*;
    let e = |e: &dyn std::fmt::Display| anyhow::anyhow!("{e}");
    teleop_node::plot::register_fonts()?;
    let root = BitMapBackend::new(path, (1400, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let most = placed.iter().map(|(_, c)| c.runs.len()).max().unwrap_or(0);
    let fewest = placed.iter().map(|(_, c)| c.runs.len()).min().unwrap_or(0);
    let runs = if fewest == most {
        format!("{most}")
    } else {
        format!("{fewest}-{most}")
    };
    let conditions: Vec<(f64, &Condition)> = placed
        .iter()
        .filter_map(|(x, c)| Some(((*x)?, c)))
        .collect();
    let uncapped = placed.iter().find(|(x, _)| x.is_none()).map(|(_, c)| c);
    let root = root
        .titled(
            &format!(
                "{task}: success and completion time vs {} ({runs} seeded runs per point)",
                against.title()
            ),
            ("sans-serif", 26),
        )
        .map_err(|x| e(&x))?;
    let [left, right] = {
        let v = root.split_evenly((1, 2));
        [v[0].clone(), v[1].clone()]
    };
    let x_max = conditions.iter().map(|(x, _)| *x).fold(
        match against {
            Against::RoundTrip => 50.0_f64,
            Against::Loss | Against::Rate => 1.0,
        },
        f64::max,
    ) * 1.1;
    let thesis = thesis_figures(task);
    // Success rate.
    let mut chart = ChartBuilder::on(&left)
        .caption("success rate", ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x_max, 0.0..105.0)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc(against.axis())
        .y_desc("runs judged a success (%)")
        .draw()
        .map_err(|x| e(&x))?;
    let pts: Vec<(f64, f64)> = conditions
        .iter()
        .map(|(x, c)| (*x, c.success_pct))
        .collect();
    chart
        .draw_series(LineSeries::new(pts.clone(), GREEN.stroke_width(3)))
        .map_err(|x| e(&x))?
        .label("this system (simulated world and operator)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 14, y)], GREEN.stroke_width(3)));
    chart
        .draw_series(pts.iter().map(|&p| Circle::new(p, 6, GREEN.filled())))
        .map_err(|x| e(&x))?;
    thesis_lines(&mut chart, thesis, (0.0, x_max), |f| {
        (f.success_pct, format!("{:.0} %", f.success_pct))
    })?;
    if let Some(u) = uncapped {
        reference_line(&mut chart, (0.0, x_max), u.success_pct, "uncapped")?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|x| e(&x))?;
    // Completion time.
    let y_max = conditions
        .iter()
        .filter_map(|(_, c)| c.completion_p90_s)
        .chain(uncapped.and_then(|u| u.completion_p90_s))
        .chain(thesis.iter().map(|f| f.time_s))
        .fold(10.0_f64, f64::max)
        * 1.2;
    let mut chart = ChartBuilder::on(&right)
        .caption("completion time of the successful runs", ("sans-serif", 20))
        .margin(14)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x_max, 0.0..y_max)
        .map_err(|x| e(&x))?;
    chart
        .configure_mesh()
        .x_desc(against.axis())
        .y_desc("completion time (s)")
        .draw()
        .map_err(|x| e(&x))?;
    let mean: Vec<(f64, f64)> = conditions
        .iter()
        .filter_map(|(x, c)| Some((*x, c.completion_mean_s?)))
        .collect();
    let p90: Vec<(f64, f64)> = conditions
        .iter()
        .filter_map(|(x, c)| Some((*x, c.completion_p90_s?)))
        .collect();
    chart
        .draw_series(LineSeries::new(mean.clone(), BLACK.stroke_width(3)))
        .map_err(|x| e(&x))?
        .label("mean")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 14, y)], BLACK.stroke_width(3)));
    chart
        .draw_series(mean.iter().map(|&p| Circle::new(p, 6, BLACK.filled())))
        .map_err(|x| e(&x))?;
    chart
        .draw_series(LineSeries::new(p90, RED.stroke_width(2)))
        .map_err(|x| e(&x))?
        .label("90th percentile")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 14, y)], RED.stroke_width(2)));
    thesis_lines(&mut chart, thesis, (0.0, x_max), |f| {
        (f.time_s, format!("{:.1} s", f.time_s))
    })?;
    if let Some(t) = uncapped.and_then(|u| u.completion_mean_s) {
        reference_line(&mut chart, (0.0, x_max), t, "uncapped, mean")?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(|x| e(&x))?;
    root.present().map_err(|x| e(&x))?;
    Ok(())
}

/// A dashed grey horizontal line at `y` across `x`, in the legend as `label` (the
/// uncapped link's figure beside the capped ones).
fn reference_line(
    chart: &mut Chart<'_, '_>,
    x: (f64, f64),
    y: f64,
    label: &str,
) -> anyhow::Result<()> {
    let grey = plotters::style::RGBColor(110, 110, 110);
    dashed_line(chart, x, y, grey, 4, format!("{label}: {y:.1}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(seed: u64, succeeded: bool, completion_s: Option<f64>) -> SeedRun {
        SeedRun {
            seed,
            job: Some(JobOutcome {
                lifted: true,
                succeeded,
                completion_s,
                failure: (!succeeded).then(|| "fell_off_table".to_owned()),
                judge_errors: 0,
            }),
            operator: None,
            error: None,
            report_dir: PathBuf::from(format!("seed-{seed}")),
        }
    }

    #[test]
    fn the_rate_and_times_count_the_successes_only() {
        let mut runs: Vec<SeedRun> = (0..9)
            .map(|i| run(i, true, Some(20.0 + i as f64)))
            .collect();
        runs.push(run(9, false, None));
        let s = SeedsSummary::new(crate::tasks::PICK_JOB, None, runs);
        assert_eq!(s.succeeded, 9);
        assert_eq!(s.success_pct, 90.0);
        assert_eq!(s.completion_mean_s, Some(24.0));
        // Nearest rank over 9 times: the 9th smallest (ceil(8.1) = 9).
        assert_eq!(s.completion_p90_s, Some(28.0));
        // Table 6.1's 100 % is missed, Table 7.1's 90 % met; both times missed/met.
        let verdicts: Vec<(bool, Option<bool>)> = s
            .thesis
            .iter()
            .map(|c| (c.success_met, c.time_met))
            .collect();
        assert_eq!(verdicts, [(false, Some(false)), (true, Some(true))]);
        let text = s.text();
        assert!(text.contains("success 9/10 (90 %)"), "{text}");
        assert!(
            text.contains("seed 9      failed (fell off table)"),
            "{text}"
        );
        assert!(text.contains("MISSED"), "{text}");
    }

    #[test]
    fn a_run_without_a_verdict_is_a_failure_and_no_runs_meet_nothing() {
        let mut lost = run(3, true, Some(10.0));
        lost.job = None;
        lost.error = Some("node remote_sim exited early".into());
        let s = SeedsSummary::new(crate::tasks::PICK_JOB, None, vec![lost]);
        assert_eq!(s.succeeded, 0);
        assert_eq!(s.completion_mean_s, None);
        assert!(
            s.thesis
                .iter()
                .all(|c| !c.success_met && c.time_met.is_none())
        );
        assert!(s.text().contains("no verdict"), "{}", s.text());
        let none = SeedsSummary::new(crate::tasks::PICK_JOB, None, Vec::new());
        assert_eq!(none.success_pct, 0.0);
        assert!(none.thesis.iter().all(|c| !c.success_met));
        assert!(thesis_figures("fader").is_empty());
    }

    #[test]
    fn the_summary_is_written_as_json_and_a_picture() {
        let dir = std::env::temp_dir().join(format!("teleop-seeds-test-{}", std::process::id()));
        let wan = crate::site_link::parse_wan("delay_ms=25").expect("valid");
        let s = SeedsSummary::new(
            crate::tasks::PICK_JOB,
            Some(&wan),
            vec![run(1, true, Some(23.4)), run(2, false, None)],
        );
        s.write_files(&dir).expect("written");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).expect("json"))
                .expect("parses");
        assert_eq!(json["succeeded"], 1);
        assert_eq!(json["round_trip_ms"], 50.0);
        assert_eq!(json["runs"][1]["job"]["failure"], "fell_off_table");
        let png = std::fs::read(dir.join("summary.png")).expect("png");
        assert!(png.starts_with(b"\x89PNG"), "not a PNG");
        // Read back for the picture against the round trip.
        let out = dir.join("vs-rtt.png");
        plot(&SeedsPlotArgs {
            dirs: vec![dir.clone()],
            out: out.clone(),
            against: Against::RoundTrip,
        })
        .expect("plotted");
        assert!(std::fs::read(&out).expect("png").starts_with(b"\x89PNG"));
        let err = plot(&SeedsPlotArgs {
            dirs: vec![dir.join("nowhere")],
            out: out.clone(),
            against: Against::RoundTrip,
        })
        .expect_err("no summary");
        assert!(format!("{err:#}").contains("nowhere"), "{err:#}");
        // A capped link beside the uncapped one: against the cap, the uncapped is the
        // reference; against the loss, both sit at 0 % and are refused by name.
        let capped = dir.join("capped");
        let capped_wan = crate::site_link::parse_wan("delay_ms=25 rate_mbit=2").expect("valid");
        SeedsSummary::new(
            crate::tasks::PICK_JOB,
            Some(&capped_wan),
            vec![run(1, true, Some(25.0))],
        )
        .write_files(&capped)
        .expect("written");
        let vs_rate = dir.join("vs-rate.png");
        plot(&SeedsPlotArgs {
            dirs: vec![capped.clone(), dir.clone()],
            out: vs_rate.clone(),
            against: Against::Rate,
        })
        .expect("plotted against the cap");
        assert!(
            std::fs::read(&vs_rate)
                .expect("png")
                .starts_with(b"\x89PNG")
        );
        let err = plot(&SeedsPlotArgs {
            dirs: vec![capped, dir.clone()],
            out,
            against: Against::Loss,
        })
        .expect_err("two summaries at 0 % loss");
        assert!(format!("{err:#}").contains("rate_mbit=2"), "{err:#}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

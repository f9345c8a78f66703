//! `teleop sweep-report DIR`: the WAN-condition sweep's table, plots and checks, from
//! what `deploy/compose/sweep.sh` recorded for each condition (one numbered directory
//! each): `condition.txt` (name, link settings), the operator site's end-of-run report
//! (`report.json`), the robot LAN's listeners (`r-teleop-wrist_pose.jsonl`,
//! `r-hand-joint_targets.jsonl`, `r-teleop-status.jsonl`) and the operator LAN's
//! (`l-image-compressed.jsonl`, the remote camera's top view).
//!
//! Checked for every condition, from the robot-site controllers' own counters and the
//! robot LAN's recordings:
//!
//! * no command older than its deadline was executed: the oldest wrist pose the arm
//!   controller took, and the oldest finger targets the hand controller took, were
//!   within their limit (`<topic>.executed_max_age_us <= <topic>.execute_limit_us`);
//! * none was executed out of order (`<topic>.executed_out_of_order` = 0);
//! * the policy: every status in which the arm was Active (moving under command)
//!   follows a fresh wrist pose on the robot LAN within the arm's pose deadline, every
//!   Active status of the hand follows fresh targets within the hand's command
//!   timeout: when the commands are late the arm stops and the hand holds.
//!
//! Writes `sweep.md` (table and checks), `sweep.json` and `sweep.png` into DIR; fails
//! when a check fails or a condition's recordings are missing.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use serde::Serialize;
use serde_json::Value;
use teleop_msgs::{Lifecycle, NodeStatus};

/// How long after a fresh wrist pose the arm may still be Active: its pose deadline
/// (`pose_deadline_s`, 0.1 s) plus the status's own delay on the LAN.
const ARM_ACTIVE_AFTER_POSE_S: f64 = 0.1 + 0.05;
/// The same for the hand: its command timeout (`command_timeout_s`, 0.2 s) + 0.05 s.
const HAND_ACTIVE_AFTER_TARGETS_S: f64 = 0.2 + 0.05;
/// The smallest bandwidth cap under which the camera views must give way to the
/// feedback: above what the feedback topics need on their own, about 1.1 Mbit/s (each
/// 10 ms a PR2 state of 316 bytes, a Shadow state of about 660, the pressures, each with
/// its attachment, Zenoh's and TLS's framing: docs/network.md; at 1 Mbit/s the feedback
/// was late with the views paced down to 0.8 Hz). Below the two JPEG views' 1.8 Mbit/s
/// plus that, something must be dropped, and it must be views.
const GIVE_WAY_MIN_MBIT: f64 = 2.0;

#[derive(Debug, Clone, clap::Args)]
pub struct SweepArgs {
    /// The sweep directory (one numbered directory per condition).
    pub dir: PathBuf,
}

/// A distribution's median and 99th percentile (ms), and its sample count.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct Spread {
    pub samples: usize,
    pub p50_ms: f64,
    pub p99_ms: f64,
}

impl Spread {
    fn of_seconds(mut v: Vec<f64>) -> Self {
        v.retain(|x| x.is_finite());
        if v.is_empty() {
            return Self::default();
        }
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize] * 1e3;
        Self {
            samples: v.len(),
            p50_ms: at(0.5),
            p99_ms: at(0.99),
        }
    }
}

/// One received sample of a listener: sent (publisher clock), received (listener),
/// and the message's own stamp (capture time), s.
#[derive(Debug, Clone, Copy)]
struct Arrival {
    sent_s: f64,
    received_s: f64,
    stamp_s: f64,
}

/// What one condition measured.
#[derive(Debug, Clone, Serialize)]
pub struct ConditionResult {
    pub name: String,
    pub settings: String,
    /// Wrist pose, wrist tracker -> robot LAN.
    pub wrist_one_way: Spread,
    pub wrist_rate_hz: f64,
    /// Finger targets, hand inference -> robot LAN.
    pub targets_one_way: Spread,
    pub targets_rate_hz: f64,
    /// Depth frame capture -> its finger targets on the robot LAN.
    pub frame_to_command: Spread,
    /// PR2 joints -> operator site (the report's feedback stage).
    pub feedback: Spread,
    /// How old the operator site's newest PR2 joint state was just before each next
    /// one arrived (the listener on the operator's LAN): its latency plus the gap.
    pub feedback_staleness: Spread,
    /// One remote camera view at the operator site, Hz.
    pub camera_view_rate_hz: f64,
    /// PR2 tracking error while clutched (mean, m) and its sample count.
    pub pr2_error_mean_m: Option<f64>,
    pub pr2_samples: u64,
    pub engagements: u64,
    /// Counter increases over the condition at the robot site.
    pub wrist_refused_late: u64,
    pub targets_refused_late: u64,
    pub arm_stale_stops: u64,
    pub hand_stale_holds: u64,
    /// The oldest command the controllers took (ms, over the system's life) and the
    /// limit.
    pub wrist_executed_max_age_ms: Option<f64>,
    pub wrist_limit_ms: Option<f64>,
    pub targets_executed_max_age_ms: Option<f64>,
    pub targets_limit_ms: Option<f64>,
    pub checks: Vec<Check>,
}

#[derive(Debug, Clone, Serialize)]
pub struct Check {
    pub name: String,
    pub ok: bool,
    pub detail: String,
}

fn num(v: &Value, path: &[&str]) -> Option<f64> {
    let mut v = v;
    for p in path {
        v = v.get(p)?;
    }
    v.as_f64()
}

fn read_jsonl(path: &Path) -> anyhow::Result<Vec<Value>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Ok(text
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .collect())
}

fn arrivals(path: &Path) -> anyhow::Result<Vec<Arrival>> {
    Ok(read_jsonl(path)?
        .iter()
        .filter_map(|v| {
            Some(Arrival {
                sent_s: num(v, &["_meta", "sent_s"])?,
                received_s: num(v, &["_meta", "received_s"])?,
                stamp_s: num(v, &["header", "stamp", "sec"])?
                    + num(v, &["header", "stamp", "nanosec"])? * 1e-9,
            })
        })
        .collect())
}

/// Samples per second over the span of `window` (another stream recorded at the same
/// listener, dense enough to span the run): what a sparse stream (a camera view under
/// a bandwidth cap: two views 2 ms apart are not 500 Hz) delivered over the run.
/// Without a window, over its own span ([`rate_hz`]).
fn rate_over_hz(a: &[Arrival], window: &[Arrival]) -> f64 {
    match (window.first(), window.last()) {
        (Some(f), Some(l)) if l.received_s > f.received_s => {
            a.iter()
                .filter(|x| (f.received_s..=l.received_s).contains(&x.received_s))
                .count() as f64
                / (l.received_s - f.received_s)
        }
        _ => rate_hz(a),
    }
}

/// Samples per second between the first and the last arrival.
fn rate_hz(a: &[Arrival]) -> f64 {
    match (a.first(), a.last()) {
        (Some(f), Some(l)) if a.len() > 1 && l.received_s > f.received_s => {
            (a.len() - 1) as f64 / (l.received_s - f.received_s)
        }
        _ => 0.0,
    }
}

/// One status as the robot LAN's listener recorded it: when it was sent, and the message.
struct Status {
    sent_s: f64,
    msg: NodeStatus,
}

/// `node`'s statuses in the recording, in the order they were sent.
fn statuses(all: &[Value], node: &str) -> Vec<Status> {
    let mut out: Vec<Status> = all
        .iter()
        .filter(|v| v.get("node_name").and_then(Value::as_str) == Some(node))
        .filter_map(|v| {
            Some(Status {
                sent_s: num(v, &["_meta", "sent_s"])?,
                msg: serde_json::from_value(v.clone()).ok()?,
            })
        })
        .collect();
    out.sort_by(|a, b| a.sent_s.total_cmp(&b.sent_s));
    out
}

/// Increase of the counters `names` (summed) from the first status to the last (a
/// restarted node's counters start again: then the last value).
fn increase(s: &[Status], names: &[&str]) -> u64 {
    let (Some(first), Some(last)) = (s.first(), s.last()) else {
        return 0;
    };
    names
        .iter()
        .map(|n| {
            let (a, b) = (
                first.msg.counter(n).unwrap_or(0),
                last.msg.counter(n).unwrap_or(0),
            );
            if b >= a { b - a } else { b }
        })
        .sum()
}

/// Active statuses not preceded by a fresh command within `window_s`: (count of
/// Active statuses, those without).
fn active_without_fresh(
    status: &[Status],
    commands: &[Arrival],
    limit_s: f64,
    window_s: f64,
) -> (usize, Vec<f64>) {
    let active: Vec<&Status> = status
        .iter()
        .filter(|s| s.msg.lifecycle() == Some(Lifecycle::Active))
        .collect();
    let bad = active
        .iter()
        .filter(|s| {
            !commands.iter().any(|c| {
                c.received_s - c.sent_s <= limit_s
                    && c.received_s <= s.sent_s + 0.05
                    && c.received_s >= s.sent_s - window_s
            })
        })
        .map(|s| s.sent_s)
        .collect();
    (active.len(), bad)
}

fn executed_checks(
    checks: &mut Vec<Check>,
    last: Option<&Status>,
    node: &str,
    topic: &str,
) -> (Option<f64>, Option<f64>) {
    let Some(last) = last else {
        checks.push(Check {
            name: format!("{node}: status heard"),
            ok: false,
            detail: "no status from it on the robot LAN".into(),
        });
        return (None, None);
    };
    let age = last.msg.counter(&format!("{topic}.executed_max_age_us"));
    let limit = last.msg.counter(&format!("{topic}.execute_limit_us"));
    let taken = last.msg.counter(&format!("{topic}.executed")).unwrap_or(0);
    let ooo = last.msg.counter(&format!("{topic}.executed_out_of_order"));
    match (age, limit) {
        (Some(a), Some(l)) => checks.push(Check {
            name: format!("{node}: no {topic} older than its deadline executed"),
            ok: a <= l,
            detail: format!(
                "oldest taken {:.1} ms, limit {:.0} ms ({taken} taken)",
                a as f64 / 1e3,
                l as f64 / 1e3
            ),
        }),
        _ => checks.push(Check {
            name: format!("{node}: no {topic} older than its deadline executed"),
            ok: false,
            detail: format!("{topic}.executed_max_age_us / execute_limit_us not reported"),
        }),
    }
    checks.push(Check {
        name: format!("{node}: no {topic} executed out of order"),
        ok: ooo == Some(0),
        detail: match ooo {
            Some(n) => format!("{n} out of order of {taken} taken"),
            None => format!("{topic}.executed_out_of_order not reported"),
        },
    });
    (age.map(|a| a as f64 / 1e3), limit.map(|l| l as f64 / 1e3))
}

/// Reads and checks one condition's directory.
///
/// # Errors
/// A missing or unreadable recording.
pub fn condition(dir: &Path) -> anyhow::Result<ConditionResult> {
    let cond = std::fs::read_to_string(dir.join("condition.txt"))
        .with_context(|| format!("reading {}", dir.join("condition.txt").display()))?;
    let mut lines = cond.lines();
    let name = lines.next().unwrap_or_default().trim().to_owned();
    let settings = lines.next().unwrap_or_default().trim().to_owned();
    let report: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("report.json"))
            .with_context(|| format!("reading {}", dir.join("report.json").display()))?,
    )
    .with_context(|| format!("parsing {}", dir.join("report.json").display()))?;
    let wrist = arrivals(&dir.join("r-teleop-wrist_pose.jsonl"))?;
    let targets = arrivals(&dir.join("r-hand-joint_targets.jsonl"))?;
    let camera = arrivals(&dir.join("l-image-compressed.jsonl"))?;
    let pr2_at_operator = arrivals(&dir.join("l-pr2-joint_states.jsonl"))?;
    let feedback_staleness = Spread::of_seconds(staleness_s(&pr2_at_operator));
    let status = read_jsonl(&dir.join("r-teleop-status.jsonl"))?;
    let arm = statuses(&status, "pr2_arm_controller");
    let hand = statuses(&status, "shadow_hand_controller");

    let feedback = report
        .get("latency")
        .and_then(Value::as_array)
        .and_then(|a| {
            a.iter()
                .find(|s| s.get("stage").and_then(Value::as_str) == Some("PR2 joints -> feedback"))
        })
        .map(|s| Spread {
            samples: num(s, &["samples"]).unwrap_or(0.0) as usize,
            p50_ms: num(s, &["p50_ms"]).unwrap_or(f64::NAN),
            p99_ms: num(s, &["p99_ms"]).unwrap_or(f64::NAN),
        })
        .unwrap_or_default();
    let pr2_samples = num(&report, &["pr2_position_error_m", "samples"]).unwrap_or(0.0) as u64;

    let mut checks = Vec::new();
    let (wrist_age, wrist_limit) =
        executed_checks(&mut checks, arm.last(), "arm controller", "wrist_pose");
    let (targets_age, targets_limit) =
        executed_checks(&mut checks, hand.last(), "hand controller", "joint_targets");
    let policy = |checks: &mut Vec<Check>,
                  who: &str,
                  what: &str,
                  s: &[Status],
                  cmds: &[Arrival],
                  limit_ms: Option<f64>,
                  window_s: f64| {
        let limit_s = limit_ms.map_or(f64::INFINITY, |l| l * 1e-3);
        let (n, bad) = active_without_fresh(s, cmds, limit_s, window_s);
        checks.push(Check {
            name: format!("{who} Active only on fresh {what}"),
            ok: bad.is_empty(),
            detail: format!(
                "{n} Active statuses, {} without a fresh {what} in the {:.0} ms before",
                bad.len(),
                window_s * 1e3
            ),
        });
    };
    policy(
        &mut checks,
        "arm",
        "wrist pose",
        &arm,
        &wrist,
        wrist_limit,
        ARM_ACTIVE_AFTER_POSE_S,
    );
    policy(
        &mut checks,
        "hand",
        "finger targets",
        &hand,
        &targets,
        targets_limit,
        HAND_ACTIVE_AFTER_TARGETS_S,
    );

    let camera_view_rate_hz = rate_over_hz(&camera, &pr2_at_operator);
    if let Some(cap) = rate_cap_mbit(&settings)
        && cap >= GIVE_WAY_MIN_MBIT
    {
        let spec = &teleop_interfaces::topics::PR2_JOINT_STATES.spec;
        #[allow(clippy::cast_precision_loss)]
        let deadline_ms = spec.deadline_ms.unwrap_or(0) as f64;
        checks.push(Check {
            name: "camera views give way to the PR2 feedback".into(),
            ok: feedback_staleness.samples > 100 && feedback_staleness.p99_ms <= deadline_ms,
            detail: format!(
                "the operator site's newest PR2 joint state was {:.0} ms old at p99 (median {:.0} ms, {} arrivals; its deadline {deadline_ms:.0} ms); the camera view came at {camera_view_rate_hz:.1} Hz",
                feedback_staleness.p99_ms,
                feedback_staleness.p50_ms,
                feedback_staleness.samples,
            ),
        });
    }

    Ok(ConditionResult {
        name,
        settings,
        wrist_one_way: Spread::of_seconds(wrist.iter().map(|a| a.received_s - a.sent_s).collect()),
        wrist_rate_hz: rate_hz(&wrist),
        targets_one_way: Spread::of_seconds(
            targets.iter().map(|a| a.received_s - a.sent_s).collect(),
        ),
        targets_rate_hz: rate_hz(&targets),
        frame_to_command: Spread::of_seconds(
            targets.iter().map(|a| a.received_s - a.stamp_s).collect(),
        ),
        feedback,
        feedback_staleness,
        camera_view_rate_hz,
        pr2_error_mean_m: (pr2_samples > 0)
            .then(|| num(&report, &["pr2_position_error_m", "mean"]))
            .flatten(),
        pr2_samples,
        engagements: increase(&arm, &["arm.engagements"]),
        wrist_refused_late: increase(
            &arm,
            &["wrist_pose.rejected_stale", "wrist_pose.rejected_expired"],
        ),
        targets_refused_late: increase(
            &hand,
            &[
                "joint_targets.rejected_stale",
                "joint_targets.rejected_expired",
            ],
        ),
        arm_stale_stops: increase(&arm, &["arm.stop.stale_wrist_pose"]),
        hand_stale_holds: increase(&hand, &["hand.hold.stale_target"]),
        wrist_executed_max_age_ms: wrist_age,
        wrist_limit_ms: wrist_limit,
        targets_executed_max_age_ms: targets_age,
        targets_limit_ms: targets_limit,
        checks,
    })
}

/// Before each arrival after the first, how old the newest state the receiver held
/// was: the arrival time minus the previous sample's stamp, s (in arrival order).
fn staleness_s(a: &[Arrival]) -> Vec<f64> {
    a.windows(2)
        .map(|w| w[1].received_s - w[0].stamp_s)
        .collect()
}

/// The bandwidth cap of a condition's link settings, read as the link emulator reads
/// them (`wan_link ctl set ...`: `rate_mbit=0` is none), Mbit/s; `None` also for
/// settings it would refuse.
fn rate_cap_mbit(settings: &str) -> Option<f64> {
    let words: Vec<&str> = settings.split_whitespace().collect();
    teleop_wan_link::Impairment::default()
        .with(&words)
        .ok()?
        .rate_mbit
}

fn ms(s: &Spread) -> String {
    if s.samples == 0 {
        "none".into()
    } else {
        format!("{:.0} / {:.0}", s.p50_ms, s.p99_ms)
    }
}

/// The Markdown table and the checks.
#[must_use]
pub fn markdown(results: &[ConditionResult]) -> String {
    let mut t = String::new();
    t.push_str(
        "| condition | link (each way) | wrist pose p50 / p99 ms, Hz | finger targets p50 / p99 ms, Hz \
         | depth frame -> targets at robot p50 / p99 ms | feedback p50 / p99 ms \
         | newest PR2 state's age at the operator p50 / p99 ms | camera view Hz \
         | PR2 error mean (clutched samples) | engaged | late commands refused (arm / hand) \
         | arm stops on stale pose / hand holds on stale targets |\n",
    );
    t.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in results {
        let _ = writeln!(
            t,
            "| {} | {} | {}, {:.0} | {}, {:.1} | {} | {} | {} | {:.1} | {} | {} | {} / {} | {} / {} |",
            r.name,
            r.settings,
            ms(&r.wrist_one_way),
            r.wrist_rate_hz,
            ms(&r.targets_one_way),
            r.targets_rate_hz,
            ms(&r.frame_to_command),
            ms(&r.feedback),
            ms(&r.feedback_staleness),
            r.camera_view_rate_hz,
            match (r.pr2_error_mean_m, r.engagements) {
                (Some(m), _) => format!("{:.1} cm ({})", m * 100.0, r.pr2_samples),
                (None, 0) => "never clutched".to_owned(),
                (None, _) => "no PR2 feedback in time".to_owned(),
            },
            r.engagements,
            r.wrist_refused_late,
            r.targets_refused_late,
            r.arm_stale_stops,
            r.hand_stale_holds,
        );
    }
    t.push_str("\nChecks:\n\n");
    for r in results {
        for c in &r.checks {
            let _ = writeln!(
                t,
                "- {} {}: {} ({})",
                if c.ok { "ok " } else { "BAD" },
                r.name,
                c.name,
                c.detail
            );
        }
    }
    t
}

/// The sweep's plots: one-way latencies, frame -> command, delivered rates and the PR2
/// error per condition.
///
/// # Errors
/// Font or drawing errors.
pub fn write_png(results: &[ConditionResult], path: &Path) -> anyhow::Result<()> {
    use plotters::prelude::*;
    teleop_node::plot::register_fonts()?;
    let n = results.len().max(1);
    let names: Vec<String> = results.iter().map(|r| r.name.clone()).collect();
    let root = BitMapBackend::new(path, (1600, 1900)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow::anyhow!("{e}"))?;
    let root = root
        .titled(
            "WAN-condition sweep: pick_and_place across the two compose sites",
            ("sans-serif", 30),
        )
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let panels = root.split_evenly((4, 1));
    let label = |v: &SegmentValue<usize>| match v {
        SegmentValue::CenterOf(i) => names.get(*i).cloned().unwrap_or_default(),
        _ => String::new(),
    };
    // (panel title, y label, series: (legend, colour, dashed, value per condition))
    type Series = (String, RGBColor, bool, Vec<Option<f64>>);
    let rate_ref = |f: fn(&ConditionResult) -> f64| {
        let base = results.first().map_or(0.0, f);
        results
            .iter()
            .map(|r| (base > 0.0).then(|| 100.0 * f(r) / base))
            .collect::<Vec<_>>()
    };
    let spread = |f: fn(&ConditionResult) -> Spread, p99: bool| {
        results
            .iter()
            .map(|r| {
                let s = f(r);
                (s.samples > 0).then_some(if p99 { s.p99_ms } else { s.p50_ms })
            })
            .collect::<Vec<_>>()
    };
    let panels_data: Vec<(&str, &str, Vec<Series>)> = vec![
        (
            "One-way latency per topic (p50 solid, p99 dashed)",
            "latency (ms)",
            vec![
                (
                    "wrist pose p50 (operator -> robot LAN)".into(),
                    BLUE,
                    false,
                    spread(|r| r.wrist_one_way, false),
                ),
                (
                    "wrist pose p99".into(),
                    BLUE,
                    true,
                    spread(|r| r.wrist_one_way, true),
                ),
                (
                    "finger targets p50 (operator -> robot LAN)".into(),
                    GREEN,
                    false,
                    spread(|r| r.targets_one_way, false),
                ),
                (
                    "finger targets p99".into(),
                    GREEN,
                    true,
                    spread(|r| r.targets_one_way, true),
                ),
                (
                    "feedback p50 (PR2 joints -> operator site)".into(),
                    RED,
                    false,
                    spread(|r| r.feedback, false),
                ),
                (
                    "feedback p99".into(),
                    RED,
                    true,
                    spread(|r| r.feedback, true),
                ),
            ],
        ),
        (
            "Depth frame capture -> its finger targets on the robot LAN",
            "latency (ms)",
            vec![
                (
                    "p50".into(),
                    MAGENTA,
                    false,
                    spread(|r| r.frame_to_command, false),
                ),
                (
                    "p99".into(),
                    MAGENTA,
                    true,
                    spread(|r| r.frame_to_command, true),
                ),
            ],
        ),
        (
            "Delivered rate, % of the first condition's",
            "rate (%)",
            vec![
                (
                    "wrist pose at the robot LAN".into(),
                    BLUE,
                    false,
                    rate_ref(|r| r.wrist_rate_hz),
                ),
                (
                    "finger targets at the robot LAN".into(),
                    GREEN,
                    false,
                    rate_ref(|r| r.targets_rate_hz),
                ),
                (
                    "remote camera view at the operator site".into(),
                    RED,
                    false,
                    rate_ref(|r| r.camera_view_rate_hz),
                ),
            ],
        ),
        (
            "PR2 palm error vs the scaled operator motion while clutched (mean; none: not clutched or no feedback)",
            "error (cm)",
            vec![(
                "PR2 error mean".into(),
                BLACK,
                false,
                results
                    .iter()
                    .map(|r| r.pr2_error_mean_m.map(|m| m * 100.0))
                    .collect(),
            )],
        ),
    ];
    for (area, (title, y_label, series)) in panels.iter().zip(panels_data) {
        let y_max = series
            .iter()
            .flat_map(|s| s.3.iter().flatten().copied())
            .fold(0.0, f64::max)
            .max(1.0)
            * 1.15;
        let mut chart = ChartBuilder::on(area)
            .caption(title, ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((0..n - 1).into_segmented(), 0.0..y_max)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        chart
            .configure_mesh()
            .x_desc("WAN condition (wan_link settings, each way)")
            .y_desc(y_label)
            .x_labels(n)
            .x_label_formatter(&label)
            .y_label_formatter(&teleop_node::plot::tick_label)
            .draw()
            .map_err(|e| anyhow::anyhow!("{e}"))?;
        for (legend, color, dashed, values) in series {
            let pts: Vec<(SegmentValue<usize>, f64)> = values
                .iter()
                .enumerate()
                .filter_map(|(i, v)| v.map(|v| (SegmentValue::CenterOf(i), v)))
                .collect();
            let style = ShapeStyle::from(&color).stroke_width(if dashed { 1 } else { 2 });
            // Lines join neighbouring conditions only: a condition without a value
            // breaks the line.
            for (k, run) in runs(&values).into_iter().enumerate() {
                let run: Vec<(SegmentValue<usize>, f64)> = run
                    .into_iter()
                    .map(|(i, v)| (SegmentValue::CenterOf(i), v))
                    .collect();
                let drawn = if dashed {
                    chart.draw_series(DashedLineSeries::new(run, 8, 6, style))
                } else {
                    chart.draw_series(LineSeries::new(run, style))
                }
                .map_err(|e| anyhow::anyhow!("{e}"))?;
                if k == 0 {
                    drawn
                        .label(legend.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                }
            }
            chart
                .draw_series(
                    pts.iter()
                        .map(|p| Circle::new(p.clone(), 4, color.filled())),
                )
                .map_err(|e| anyhow::anyhow!("{e}"))?;
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    root.present().map_err(|e| anyhow::anyhow!("{e}"))?;
    Ok(())
}

/// The values' runs of neighbouring conditions that have one: `(index, value)`.
fn runs(values: &[Option<f64>]) -> Vec<Vec<(usize, f64)>> {
    let mut out: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut current = Vec::new();
    for (i, v) in values.iter().enumerate() {
        match v {
            Some(v) => current.push((i, *v)),
            None if !current.is_empty() => out.push(std::mem::take(&mut current)),
            None => {}
        }
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}

/// Reads every condition under `args.dir`, writes the table, JSON and plots, prints the
/// table and checks; fails if a check failed.
///
/// # Errors
/// Missing recordings, file errors, failed checks.
pub fn run(args: &SweepArgs) -> anyhow::Result<()> {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(&args.dir)
        .with_context(|| format!("reading {}", args.dir.display()))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.join("condition.txt").is_file())
        .collect();
    dirs.sort();
    if dirs.is_empty() {
        bail!(
            "no condition directories (with condition.txt) in {}",
            args.dir.display()
        );
    }
    let mut results = Vec::new();
    for d in &dirs {
        let r = condition(d).with_context(|| format!("condition {}", d.display()))?;
        results.push(r);
    }
    let md = markdown(&results);
    print!("{md}");
    std::fs::write(args.dir.join("sweep.md"), &md)?;
    std::fs::write(
        args.dir.join("sweep.json"),
        serde_json::to_string_pretty(&results)?,
    )?;
    write_png(&results, &args.dir.join("sweep.png"))?;
    println!(
        "sweep: {} conditions; table {}, plots {}",
        results.len(),
        args.dir.join("sweep.md").display(),
        args.dir.join("sweep.png").display()
    );
    let bad: Vec<String> = results
        .iter()
        .flat_map(|r| {
            r.checks
                .iter()
                .filter(|c| !c.ok)
                .map(move |c| format!("{}: {}", r.name, c.name))
        })
        .collect();
    if !bad.is_empty() {
        bail!("{} check(s) failed: {}", bad.len(), bad.join("; "));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(t: f64, lifecycle: Lifecycle, counter: (&str, u64)) -> Status {
        Status {
            sent_s: t,
            msg: NodeStatus {
                node_name: "pr2_arm_controller".into(),
                lifecycle_state: lifecycle as u8,
                counter_names: vec![counter.0.into()],
                counter_values: vec![counter.1],
                ..NodeStatus::default()
            },
        }
    }

    fn pose(sent: f64, received: f64) -> Arrival {
        Arrival {
            sent_s: sent,
            received_s: received,
            stamp_s: sent,
        }
    }

    #[test]
    fn active_needs_a_fresh_command_shortly_before() {
        let e = ("arm.engagements", 1);
        let s = [
            status(10.0, Lifecycle::Active, e),
            status(11.0, Lifecycle::Inactive, e),
            status(12.0, Lifecycle::Active, e),
        ];
        // Fresh before the first, only a late one before the third.
        let c = [pose(9.94, 9.95), pose(11.7, 11.95)];
        let (n, bad) = active_without_fresh(&s, &c, 0.12, 0.15);
        assert_eq!(n, 2);
        assert_eq!(bad, vec![12.0]);
    }

    #[test]
    fn staleness_is_the_wait_for_the_next_state_plus_the_held_ones_age() {
        // States stamped every 10 ms, each arriving 20 ms after its stamp, then a
        // burst: three arriving together 100 ms late.
        let a = |stamp: f64, received: f64| Arrival {
            sent_s: stamp,
            received_s: received,
            stamp_s: stamp,
        };
        let v = [
            a(0.00, 0.02),
            a(0.01, 0.03),
            a(0.02, 0.12),
            a(0.03, 0.12),
            a(0.04, 0.12),
        ];
        let s = staleness_s(&v);
        let want = [0.03, 0.11, 0.10, 0.09];
        assert_eq!(s.len(), want.len());
        for (got, want) in s.iter().zip(want) {
            assert!((got - want).abs() < 1e-9, "{s:?}");
        }
        assert!(staleness_s(&v[..1]).is_empty());
    }

    #[test]
    fn the_cap_is_read_from_the_settings() {
        assert_eq!(rate_cap_mbit("delay_ms=20 rate_mbit=2"), Some(2.0));
        assert_eq!(rate_cap_mbit("rate_mbit=0.5"), Some(0.5));
        assert_eq!(rate_cap_mbit("delay_ms=20 rate_mbit=0"), None);
        assert_eq!(rate_cap_mbit("delay_ms=200"), None);
        assert_eq!(rate_cap_mbit("rate_mbit=fast"), None);
    }

    #[test]
    fn spread_and_rate() {
        let s = Spread::of_seconds((1..=100).map(|i| f64::from(i) * 1e-3).collect());
        assert_eq!(s.samples, 100);
        assert!((s.p50_ms - 51.0).abs() < 1e-9, "{}", s.p50_ms);
        assert!((s.p99_ms - 99.0).abs() < 1e-9, "{}", s.p99_ms);
        let a: Vec<Arrival> = (0..11).map(|i| pose(0.0, f64::from(i) * 0.1)).collect();
        assert!((rate_hz(&a) - 10.0).abs() < 1e-9);
        assert_eq!(rate_hz(&a[..1]), 0.0);
        // Two views 2 ms apart during a 1 s run: 2 Hz over the run, not 500.
        let views = [pose(0.0, 0.500), pose(0.0, 0.502)];
        assert!((rate_hz(&views) - 500.0).abs() < 1e-6);
        assert!((rate_over_hz(&views, &a) - 2.0).abs() < 1e-9);
        assert_eq!(rate_over_hz(&[], &a), 0.0);
        // Without a window, its own span.
        assert!((rate_over_hz(&a, &[]) - 10.0).abs() < 1e-9);
    }

    #[test]
    fn lines_break_where_a_condition_has_no_value() {
        let r = runs(&[Some(1.0), Some(2.0), None, Some(3.0), None, None]);
        assert_eq!(r, vec![vec![(0, 1.0), (1, 2.0)], vec![(3, 3.0)]]);
        assert!(runs(&[None]).is_empty());
    }

    #[test]
    fn counters_increase_across_a_restart() {
        let mk = |v| status(0.0, Lifecycle::Inactive, ("x", v));
        assert_eq!(increase(&[mk(5), mk(9)], &["x"]), 4);
        assert_eq!(increase(&[mk(5), mk(2)], &["x"]), 2);
        assert_eq!(increase(&[], &["x"]), 0);
    }
}

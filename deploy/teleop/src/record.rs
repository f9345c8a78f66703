//! `teleop report`: the end-of-run report of a system someone else started (the
//! docker-compose sites, machines of a lab): subscribes to what the report needs, and
//! when the operator-site simulator's task is done (`--until-task-done`), after
//! `--duration-s`, or on SIGINT/SIGTERM, prints the report and writes it as JSON and
//! PNG. The nodes keep running; their latest status stands in for the final one.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::bail;
use teleop_bus::{Bus, BusConfig};
use teleop_interfaces::topics;
use teleop_local_site::camera_arm_node::CameraArmNodeConfig;
use teleop_msgs::NodeStatus;
use teleop_node::ZenohArgs;

/// The operator-site simulator's node name (its status says when the task is done).
const LOCAL_SIM: &str = "local_sim";
const REMOTE_SIM: &str = "remote_sim";

use crate::report::{JobOutcome, Recorder};

#[derive(Debug, Clone, clap::Args)]
pub struct ReportArgs {
    /// The task's name, for the report's title.
    #[arg(long, default_value = "unnamed")]
    pub task: String,
    /// Stop 1 s after the operator-site simulator reports its task done.
    #[arg(long)]
    pub until_task_done: bool,
    /// Stop after this many seconds (a bound with `--until-task-done`).
    #[arg(long)]
    pub duration_s: Option<f64>,
    /// Fail unless the simulator's first status arrives within this many seconds.
    #[arg(long, default_value_t = 60.0)]
    pub wait_for_system_s: f64,
    /// Where the report is written (`report.json`, `report.png`).
    #[arg(long, default_value = "teleop-report")]
    pub report_dir: PathBuf,
    /// The `camera_arm` node's config file the system runs with: the camera is judged
    /// against its goal (standoff, view direction). Without it, the built-in defaults.
    #[arg(long)]
    pub camera_arm_config: Option<PathBuf>,
}

/// Whether `s` is the operator-site simulator saying its task has run once (`teleop
/// launch --task` and `teleop report --until-task-done` stop 1 s after it).
pub fn reports_task_done(s: &NodeStatus) -> bool {
    s.node_name == LOCAL_SIM && s.counter("sim.task_repetitions").is_some_and(|n| n >= 1)
}

/// Whether `s` is the robot-site simulator saying its job has failed for good (timed
/// out, or an object fell off the table): `teleop launch --task` stops then too, so an
/// operator who can no longer finish (one waiting for feedback that a saturated link
/// delivers seconds late) does not hold a seeded series forever.
pub fn reports_job_failed(s: &NodeStatus) -> bool {
    s.node_name == REMOTE_SIM
        && JobOutcome::from_counters(|name| s.counter(name)).is_some_and(|j| j.failure.is_some())
}

pub async fn run(args: ReportArgs, zenoh: &ZenohArgs) -> anyhow::Result<()> {
    let mut cfg = BusConfig::default();
    zenoh.apply(&mut cfg);
    let bus = Bus::open(&format!("teleop_report_{}", std::process::id()), &cfg).await?;
    let status = bus.subscriber(&topics::NODE_STATUS).await?;
    let camera: CameraArmNodeConfig = match &args.camera_arm_config {
        Some(path) => teleop_node::config::load_checked(path)?,
        None => CameraArmNodeConfig::default(),
    };
    let mut recorder = Recorder::new(&bus, &args.task, "teleop report", camera.camera_arm).await?;
    tracing::info!(task = %args.task, "recording");
    let mut latest: BTreeMap<String, NodeStatus> = BTreeMap::new();
    let started = tokio::time::Instant::now();
    let bound = args
        .duration_s
        .map(|s| started + Duration::from_secs_f64(s.max(0.0)));
    let wait = Duration::from_secs_f64(args.wait_for_system_s.clamp(0.0, 3600.0));
    let stop = teleop_node::stop_signal(None);
    tokio::pin!(stop);
    let mut done_since: Option<tokio::time::Instant> = None;
    let mut seen_sim = false;
    loop {
        while let Some(r) = status.try_recv() {
            if r.msg.node_name == LOCAL_SIM {
                if !seen_sim {
                    tracing::info!("operator-site simulator seen");
                }
                seen_sim = true;
                if args.until_task_done && reports_task_done(&r.msg) {
                    done_since.get_or_insert_with(tokio::time::Instant::now);
                }
            }
            recorder.on_status(&r.msg);
            latest.insert(r.msg.node_name.clone(), r.msg);
        }
        recorder.poll();
        if !seen_sim && started.elapsed() > wait {
            bail!(
                "no status from {} within {} s: is the system running on this domain and reachable?",
                LOCAL_SIM,
                args.wait_for_system_s
            );
        }
        if done_since.is_some_and(|t| t.elapsed() > Duration::from_secs(1))
            || bound.is_some_and(|b| tokio::time::Instant::now() >= b)
        {
            break;
        }
        tokio::select! {
            () = &mut stop => break,
            () = tokio::time::sleep(Duration::from_millis(5)) => {}
        }
    }
    let report = recorder.finish(bus.now_s(), &latest);
    print!("{}", report.text());
    report.write_files(&args.report_dir)?;
    drop(status);
    bus.close().await?;
    if args.until_task_done && done_since.is_none() {
        bail!("the simulator's task did not finish before the report stopped");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(node: &str, counters: &[(&str, u64)]) -> NodeStatus {
        NodeStatus {
            node_name: node.to_owned(),
            counter_names: counters.iter().map(|(n, _)| (*n).to_owned()).collect(),
            counter_values: counters.iter().map(|(_, v)| *v).collect(),
            ..NodeStatus::default()
        }
    }

    #[test]
    fn a_run_ends_on_the_task_done_or_the_job_failed_for_good() {
        assert!(reports_task_done(&status(
            LOCAL_SIM,
            &[("sim.task_repetitions", 1)]
        )));
        assert!(!reports_task_done(&status(
            LOCAL_SIM,
            &[("sim.task_repetitions", 0)]
        )));
        assert!(!reports_task_done(&status(
            REMOTE_SIM,
            &[("sim.task_repetitions", 1)]
        )));
        let running = [
            ("job.lifted", 1),
            ("job.succeeded", 0),
            ("job.failed.timed_out", 0),
            ("job.failed.fell_off_table", 0),
        ];
        assert!(!reports_job_failed(&status(REMOTE_SIM, &running)));
        for failure in ["job.failed.timed_out", "job.failed.fell_off_table"] {
            let mut c = running;
            for (n, v) in &mut c {
                if *n == failure {
                    *v = 1;
                }
            }
            assert!(reports_job_failed(&status(REMOTE_SIM, &c)), "{failure}");
            assert!(
                !reports_job_failed(&status(LOCAL_SIM, &c)),
                "only the robot site's simulator judges the job"
            );
        }
        // A success ends the run through the operator's return, not here.
        assert!(!reports_job_failed(&status(
            REMOTE_SIM,
            &[("job.succeeded", 1)]
        )));
    }
}

//! `teleop export lerobot`: bags to a LeRobotDataset v3.0 (`teleop-dataset`).

use std::path::PathBuf;

use anyhow::Context;
use teleop_dataset::{ActionSource, EpisodeSource, ExportOptions, export_lerobot};

#[derive(Debug, clap::Subcommand)]
pub enum ExportCommand {
    /// A LeRobotDataset v3.0 (parquet tables, the camera views as MJPEG MP4, meta/):
    /// `observation.state` = the arm and hand joint positions, `action` = what the
    /// operator site sent (wrist pose, pedals, finger targets), every frame aligned to
    /// its messages' source stamps; frames missing an input are counted, not written.
    Lerobot(LerobotArgs),
}

#[derive(Debug, Clone, clap::Args)]
pub struct LerobotArgs {
    /// Bags (directories of `teleop record`, or MCAP files); their episodes follow one
    /// another in the dataset.
    #[arg(required = true)]
    pub bags: Vec<PathBuf>,
    /// The dataset's directory (must not exist).
    #[arg(long)]
    pub out: PathBuf,
    /// Frames per second.
    #[arg(long, default_value_t = 30)]
    pub fps: u32,
    /// Where episodes come from: `clutch` (each clutch engagement), `job` (the robot
    /// world's job, from the first engagement to the simulator's verdict), `whole`.
    #[arg(long, default_value = "clutch")]
    pub episodes: EpisodeSource,
    /// What `action` holds: `operator` (what the operator site sent: wrist pose, clutch,
    /// enable, motion scale, finger targets; 27) or `robot` (what the robot site's
    /// controllers sent to the robots: the arm's 7 joint velocities and the hand's 17
    /// position set points; 24; needs a `teleop record --all` recording at the robot
    /// site).
    #[arg(long, default_value = "operator")]
    pub action: ActionSource,
    /// The episodes' task text (default by `--episodes`).
    #[arg(long)]
    pub task: Option<String>,
    /// The oldest a message may be at a frame, ms, for every input (default per input:
    /// three of its nominal periods, at least two frame periods).
    #[arg(long)]
    pub max_age_ms: Option<f64>,
    /// Runs of complete frames shorter than this are dropped (and counted), s.
    #[arg(long, default_value_t = 0.5)]
    pub min_episode_s: f64,
    /// Leave the camera views out.
    #[arg(long)]
    pub no_cameras: bool,
    /// Also write the export's summary as JSON here.
    #[arg(long)]
    pub summary_json: Option<PathBuf>,
}

pub fn run(cmd: &ExportCommand) -> anyhow::Result<()> {
    let ExportCommand::Lerobot(args) = cmd;
    let opts = ExportOptions {
        fps: args.fps,
        episodes: args.episodes,
        action: args.action,
        task: args.task.clone(),
        max_age_s: args.max_age_ms.map(|ms| ms / 1e3),
        min_episode_s: args.min_episode_s,
        cameras: !args.no_cameras,
        ..ExportOptions::default()
    };
    let s = export_lerobot(&args.bags, &args.out, &opts)
        .with_context(|| format!("exporting to {}", args.out.display()))?;
    println!(
        "{}: {} episode(s), {} frame(s) at {} fps, {} video frame(s), {:.1} MB written in {:.2} s ({:.0} frames/s, {:.1} MB/s of bag read)",
        args.out.display(),
        s.episodes,
        s.frames,
        args.fps,
        s.video_frames,
        s.bytes_written as f64 / 1e6,
        s.seconds,
        s.frames as f64 / s.seconds.max(1e-9),
        s.bag_bytes as f64 / 1e6 / s.seconds.max(1e-9)
    );
    println!(
        "  {} interval(s) by {:?} ({} cut by missing inputs); {} frame(s) missing an input {:?}; {} in runs shorter than {} s",
        s.intervals,
        args.episodes,
        s.intervals_cut,
        s.frames_missing,
        s.frames_missing_input,
        s.frames_in_short_runs,
        args.min_episode_s
    );
    if !s.rejected.is_empty() {
        println!("  messages refused: {:?}", s.rejected);
    }
    if !s.inputs_absent.is_empty() {
        println!(
            "  not in the bag(s), left out: {}",
            s.inputs_absent.join(", ")
        );
    }
    if let Some(path) = &args.summary_json {
        std::fs::write(path, serde_json::to_string_pretty(&s)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

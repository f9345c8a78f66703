//! The paired dataset of the hand network (thesis ch. 3-5, "Dataset2"): for each
//! sample a random human hand (shape and pose) is retargeted to the Shadow hand, both
//! hands are rendered by the shared depth renderer from the same camera-to-palm
//! transform (an SR300-like camera on the palm side, 0.3-0.8 m away), the human image
//! gets the SR300 noise model, and both go through the one preprocessing
//! ([`teleop_hand_model::preprocess`]) into 96 x 96 tensors. Labels are the 17 Shadow
//! finger joints.
//!
//! Deterministic: sample `i` of a dataset depends on the seed and `i` only (not on the
//! number of threads). On-disk format: see [`Manifest`] and `docs/hand-inference.md`.

pub mod npy;

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use teleop_hand_model::human::{HandCapsule, HandShape, HumanHand};
use teleop_hand_model::preprocess::{Crop, PreprocessConfig, Scratch, crop_window, preprocess};
use teleop_hand_model::retarget::{RetargetSettings, Retargeter, SHADOW_FINGER_DOF};
use teleop_hand_model::sampling::{PoseKind, PoseSampler, Synergy};
use teleop_hand_model::scene::{Forearm, ShadowScene, ViewSampler, push_human};
use teleop_hand_model::{KEYPOINT_COUNT, KEYPOINT_NAMES, hand_frame};
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_render::{
    Camera, Channels, DepthNoise, DepthRange, Frame, Intrinsics, NoiseParams, Renderer, Scene,
};

/// Name of the format in manifests.
pub const FORMAT: &str = "teleop-hand-dataset";
/// Version of the generator; bumped whenever the same seed would give other samples.
pub const GENERATOR_VERSION: u32 = 2;
/// Side of the preprocessed images.
pub const IMAGE_SIZE: usize = 96;
/// Columns of `meta.npy`.
pub const META_COLUMNS: [&str; 8] = [
    "distance_m",
    "off_axis_deg",
    "hand_scale",
    "pose_kind",
    "human_foreground",
    "robot_foreground",
    "retarget_tip_error_mm",
    "attempts",
];
/// Values of the `pose_kind` column.
pub const POSE_KINDS: [&str; 7] = [
    "random",
    "open",
    "power",
    "precision",
    "pinch",
    "pointing",
    "blend",
];

/// Errors of generation and reading.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DatasetError {
    #[error("cannot access {path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {reason}")]
    Format { path: String, reason: String },
    #[error("invalid generator config: {0}")]
    Config(String),
    #[error(transparent)]
    Model(#[from] teleop_hand_model::HandModelError),
    #[error("sample {index}: no usable view in {attempts} attempts (last: {reason})")]
    NoView {
        index: u64,
        attempts: u32,
        reason: String,
    },
}

/// What to generate. Every field is recorded in the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeneratorConfig {
    /// Seed of the whole set.
    pub seed: u64,
    /// Number of pairs.
    pub count: usize,
    /// Pairs per shard directory.
    pub shard_size: usize,
    /// Hand shapes: standard deviation of the overall scale and of each segment.
    pub shape_scale_sd: f64,
    pub shape_segment_sd: f64,
    /// Camera distance from the hand centre (m).
    pub distance_m: [f64; 2],
    /// Viewing direction off the palm normal (deg): `[min, max]`.
    pub off_axis_deg: [f64; 2],
    /// Camera roll away from the fingers-up view (deg): magnitude `[min, max]`.
    pub roll_deg: [f64; 2],
    /// Error of the hand-centre estimate (mm, standard deviation per axis).
    pub centre_sd_mm: f64,
    /// Apply the SR300 noise model to the human image.
    pub noise: bool,
    /// Pose mix: fraction of uniformly random poses and of single synergies.
    pub random_fraction: f64,
    pub synergy_fraction: f64,
    /// Per-joint variation around synergies (rad).
    pub joint_sd: f64,
}

impl GeneratorConfig {
    /// The training distribution.
    #[must_use]
    pub fn training(seed: u64, count: usize) -> Self {
        let sampler = PoseSampler::default();
        let view = ViewSampler::default();
        Self {
            seed,
            count,
            shard_size: 2048,
            shape_scale_sd: 0.07,
            shape_segment_sd: 0.04,
            distance_m: [view.distance_m.0, view.distance_m.1],
            off_axis_deg: [
                view.min_off_axis_rad.to_degrees(),
                view.max_off_axis_rad.to_degrees(),
            ],
            roll_deg: [view.roll_rad.0.to_degrees(), view.roll_rad.1.to_degrees()],
            centre_sd_mm: view.centre_sd_m * 1000.0,
            noise: true,
            random_fraction: sampler.random,
            synergy_fraction: sampler.synergy,
            joint_sd: sampler.joint_sd,
        }
    }

    /// Named presets: `train`, `test` (same distribution), `ood-views` (45-75 deg off
    /// the palm normal), `ood-far` (0.8-1.5 m), `ood-shapes` (twice the shape
    /// variation), `ood-roll` (camera rolled 45-90 deg).
    ///
    /// # Errors
    /// [`DatasetError::Config`] for an unknown name.
    pub fn preset(name: &str, seed: u64, count: usize) -> Result<Self, DatasetError> {
        let mut c = Self::training(seed, count);
        match name {
            "train" | "test" => {}
            "ood-views" => c.off_axis_deg = [45.0, 75.0],
            "ood-far" => c.distance_m = [0.8, 1.5],
            "ood-roll" => c.roll_deg = [45.0, 90.0],
            "ood-shapes" => {
                c.shape_scale_sd = 0.12;
                c.shape_segment_sd = 0.08;
            }
            other => {
                return Err(DatasetError::Config(format!(
                    "unknown preset {other:?} (train, test, ood-views, ood-far, ood-shapes, ood-roll)"
                )));
            }
        }
        Ok(c)
    }

    /// Checks ranges.
    ///
    /// # Errors
    /// [`DatasetError::Config`] naming the field.
    pub fn validate(&self) -> Result<(), DatasetError> {
        let bad = |what: &str| Err(DatasetError::Config(what.to_owned()));
        let finite = [
            self.shape_scale_sd,
            self.shape_segment_sd,
            self.distance_m[0],
            self.distance_m[1],
            self.off_axis_deg[0],
            self.off_axis_deg[1],
            self.centre_sd_mm,
            self.roll_deg[0],
            self.roll_deg[1],
            self.random_fraction,
            self.synergy_fraction,
            self.joint_sd,
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite {
            return bad("every number must be finite");
        }
        if self.count == 0 || self.shard_size == 0 {
            return bad("count and shard_size must be positive");
        }
        if !(0.2..=3.0).contains(&self.distance_m[0])
            || self.distance_m[1] < self.distance_m[0]
            || self.distance_m[1] > 3.0
        {
            return bad("distance_m must be [min, max] within 0.2-3 m");
        }
        if self.off_axis_deg[0] < 0.0
            || self.off_axis_deg[1] < self.off_axis_deg[0]
            || self.off_axis_deg[1] > 90.0
        {
            return bad("off_axis_deg must be [min, max] within 0-90 deg");
        }
        if self.roll_deg[0] < 0.0 || self.roll_deg[1] < self.roll_deg[0] || self.roll_deg[1] > 180.0
        {
            return bad("roll_deg must be [min, max] within 0-180 deg");
        }
        if self.random_fraction < 0.0
            || self.synergy_fraction < 0.0
            || self.random_fraction + self.synergy_fraction > 1.0
        {
            return bad("random_fraction + synergy_fraction must be within [0, 1]");
        }
        if self.shape_scale_sd < 0.0
            || self.shape_segment_sd < 0.0
            || self.centre_sd_mm < 0.0
            || self.joint_sd < 0.0
        {
            return bad("standard deviations must be >= 0");
        }
        Ok(())
    }
}

/// One pair.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Preprocessed human depth, `IMAGE_SIZE^2`, row-major, in [-1, 1].
    pub human: Vec<f32>,
    /// Preprocessed Shadow depth (same crop), noise-free.
    pub robot: Vec<f32>,
    /// Shadow finger joints (rad), `SHADOW_FINGER_JOINTS` order.
    pub joints: [f32; SHADOW_FINGER_DOF],
    /// Robot keypoints in the crop's pixel coordinates (u, v), 21 x 2.
    pub robot_uv: [f32; KEYPOINT_COUNT * 2],
    /// Human keypoints in the camera frame (m), 21 x 3.
    pub human_xyz: [f32; KEYPOINT_COUNT * 3],
    /// See [`META_COLUMNS`].
    pub meta: [f32; META_COLUMNS.len()],
}

/// Everything random of one attempt.
struct Draw {
    hand: HumanHand,
    posed: teleop_hand_model::human::PosedHand,
    kind: PoseKind,
    retarget: teleop_hand_model::retarget::Retarget,
    forearm: Forearm,
    view: teleop_hand_model::scene::View,
    noise_seed: u64,
    camera_from_canonical: Isometry3<f64>,
    camera_from_palm: Isometry3<f64>,
    centre: Point3<f64>,
}

/// A full camera frame of a sample's human hand (see [`Generator::full_frame`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FullFrame {
    /// `16UC1` depth (mm), row-major 640 x 480.
    pub depth_mm: Vec<u16>,
    pub intrinsics: Intrinsics,
    /// The hand-centre estimate (camera frame, m) the crop is taken around.
    pub centre_m: Point3<f64>,
    /// The true Shadow joints (rad).
    pub joints: [f64; SHADOW_FINGER_DOF],
}

/// Generates samples; one per thread.
#[derive(Debug)]
pub struct Generator {
    config: GeneratorConfig,
    retargeter: Retargeter,
    shadow: ShadowScene,
    renderer: Renderer,
    scene: Scene,
    frame: Frame,
    capsules: Vec<HandCapsule>,
    scratch: Scratch,
    intrinsics: Intrinsics,
    range: DepthRange,
    preprocess: PreprocessConfig,
}

/// Most attempts at a usable view before a sample fails.
const MAX_ATTEMPTS: u32 = 16;

impl Generator {
    /// A generator for `config`.
    ///
    /// # Errors
    /// [`DatasetError::Config`] for an invalid config.
    pub fn new(config: GeneratorConfig) -> Result<Self, DatasetError> {
        config.validate()?;
        Ok(Self {
            config,
            retargeter: Retargeter::new(RetargetSettings::default())?,
            shadow: ShadowScene::new()?,
            renderer: Renderer::new(),
            scene: Scene::new(),
            frame: Frame::new(Channels::DEPTH_ONLY),
            capsules: Vec::new(),
            scratch: Scratch::default(),
            intrinsics: Intrinsics::sr300(),
            // The SR300's working range (0.2 m near clip of the sensor ~ 0.3 m).
            range: DepthRange::new(0.2, 2.0).map_err(teleop_hand_model::HandModelError::from)?,
            preprocess: PreprocessConfig::default(),
        })
    }

    /// The config.
    #[must_use]
    pub fn config(&self) -> &GeneratorConfig {
        &self.config
    }

    /// Sample `index` of the set (deterministic).
    ///
    /// # Errors
    /// [`DatasetError::NoView`] if no attempt gave a crop with a hand in it (does not
    /// happen with the presets), [`DatasetError::Model`] for model errors.
    pub fn sample(&mut self, index: u64) -> Result<Sample, DatasetError> {
        let mut last = String::new();
        for attempt in 0..MAX_ATTEMPTS {
            let seed = mix(self.config.seed, index, u64::from(attempt));
            match self.attempt(seed, attempt)? {
                Ok(s) => return Ok(s),
                Err(reason) => last = reason,
            }
        }
        Err(DatasetError::NoView {
            index,
            attempts: MAX_ATTEMPTS,
            reason: last,
        })
    }

    /// Draws everything random of one attempt, in a fixed order (the determinism of
    /// the set depends on it).
    fn draw(&self, seed: u64) -> Result<Draw, DatasetError> {
        let c = &self.config;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let hand = HumanHand::new(HandShape::sample(
            &mut rng,
            c.shape_scale_sd,
            c.shape_segment_sd,
        ))?;
        let sampler = PoseSampler {
            random: c.random_fraction,
            synergy: c.synergy_fraction,
            joint_sd: c.joint_sd,
        };
        let (pose, kind) = sampler.sample(&mut rng);
        let posed = hand.pose(&pose);
        let kp = posed.keypoints;
        let retarget = self.retargeter.retarget(&kp, None)?;
        let forearm = Forearm::sample(&mut rng);
        let views = ViewSampler {
            distance_m: (c.distance_m[0], c.distance_m[1]),
            min_off_axis_rad: c.off_axis_deg[0].to_radians(),
            max_off_axis_rad: c.off_axis_deg[1].to_radians(),
            centre_sd_m: c.centre_sd_mm / 1000.0,
            roll_rad: (c.roll_deg[0].to_radians(), c.roll_deg[1].to_radians()),
        };
        let view = views.sample(&mut rng);
        let noise_seed = rand::Rng::random::<u64>(&mut rng);
        // Frames: canonical (human model) -> hand frame (Fig. 3.6) -> camera.
        let canonical_from_hand = hand_frame(&kp)?;
        let camera_from_hand = view.hand_from_camera.inverse();
        let camera_from_canonical = camera_from_hand * canonical_from_hand.inverse();
        let camera_from_palm: Isometry3<f64> =
            camera_from_canonical * self.retargeter.registration(&kp)?.inverse();
        let centre = camera_from_hand * view.centre_estimate_in_hand;
        Ok(Draw {
            hand,
            posed,
            kind,
            retarget,
            forearm,
            view,
            noise_seed,
            camera_from_canonical,
            camera_from_palm,
            centre,
        })
    }

    /// The full 640 x 480 SR300 depth image of sample `index`'s human hand (noise
    /// included), with the hand-centre estimate and the true joints: what a camera
    /// driver and the wrist tracker give the run-time node. Same hand, pose and view
    /// as [`Generator::sample`]'s first attempt.
    ///
    /// # Errors
    /// As [`Generator::sample`].
    pub fn full_frame(&mut self, index: u64) -> Result<FullFrame, DatasetError> {
        let d = self.draw(mix(self.config.seed, index, 0))?;
        let camera = Camera::new(self.intrinsics, self.range, Isometry3::identity());
        self.scene.clear();
        push_human(
            &mut self.scene,
            &d.hand,
            &d.posed,
            d.forearm,
            &d.camera_from_canonical,
            &mut self.capsules,
        )?;
        self.renderer.render(&self.scene, &camera, &mut self.frame);
        if self.config.noise {
            let mut noise = DepthNoise::new(NoiseParams::sr300(), d.noise_seed)
                .map_err(teleop_hand_model::HandModelError::from)?;
            noise.apply(&mut self.frame);
        }
        Ok(FullFrame {
            depth_mm: self.frame.depth_mm().to_vec(),
            intrinsics: self.intrinsics,
            centre_m: d.centre,
            joints: d.retarget.joints,
        })
    }

    fn attempt(&mut self, seed: u64, attempt: u32) -> Result<Result<Sample, String>, DatasetError> {
        let Draw {
            hand,
            posed,
            kind,
            retarget,
            forearm,
            view,
            noise_seed,
            camera_from_canonical,
            camera_from_palm,
            centre,
        } = self.draw(seed)?;
        let kp = posed.keypoints;
        let c = &self.config;

        let window = crop_window(&self.intrinsics, &centre, &self.preprocess)?;
        let Some((u0, v0, w, h)) =
            window.clipped(self.intrinsics.width(), self.intrinsics.height())
        else {
            return Ok(Err("the crop is outside the image".into()));
        };
        let k = self
            .intrinsics
            .cropped(u0, v0, w, h)
            .map_err(teleop_hand_model::HandModelError::from)?;
        let camera = Camera::new(k, self.range, Isometry3::identity());

        // Human.
        self.scene.clear();
        push_human(
            &mut self.scene,
            &hand,
            &posed,
            forearm,
            &camera_from_canonical,
            &mut self.capsules,
        )?;
        self.renderer.render(&self.scene, &camera, &mut self.frame);
        if c.noise {
            let mut noise = DepthNoise::new(NoiseParams::sr300(), noise_seed)
                .map_err(teleop_hand_model::HandModelError::from)?;
            noise.apply(&mut self.frame);
        }
        let (human, human_fg) = match self.crop(&k, &centre)? {
            Ok(c) => c,
            Err(reason) => return Ok(Err(format!("human image: {reason}"))),
        };

        // Robot, same camera-to-palm transform, no noise.
        self.scene.clear();
        self.shadow
            .push(&mut self.scene, &retarget.joints, &camera_from_palm)?;
        self.renderer.render(&self.scene, &camera, &mut self.frame);
        let (robot, robot_fg) = match self.crop(&k, &centre)? {
            Ok(c) => c,
            Err(reason) => return Ok(Err(format!("robot image: {reason}"))),
        };

        // Labels and keypoints.
        let mut joints = [0.0f32; SHADOW_FINGER_DOF];
        for (o, v) in joints.iter_mut().zip(retarget.joints) {
            *o = v as f32;
        }
        let robot_kp = self.retargeter.shadow_keypoints(&retarget.joints);
        let mut robot_uv = [0.0f32; KEYPOINT_COUNT * 2];
        let sx = IMAGE_SIZE as f64 / window.width as f64;
        let sy = IMAGE_SIZE as f64 / window.height as f64;
        for (i, p) in robot_kp.0.iter().enumerate() {
            let pc: Point3<f64> = camera_from_palm * p;
            let (u, v) = self.intrinsics.project(&pc).unwrap_or((-1.0, -1.0));
            robot_uv[2 * i] = ((u - window.u0 as f64 + 0.5) * sx - 0.5) as f32;
            robot_uv[2 * i + 1] = ((v - window.v0 as f64 + 0.5) * sy - 0.5) as f32;
        }
        let mut human_xyz = [0.0f32; KEYPOINT_COUNT * 3];
        for (i, p) in kp.0.iter().enumerate() {
            let pc = camera_from_canonical * p;
            for a in 0..3 {
                human_xyz[3 * i + a] = pc[a] as f32;
            }
        }
        let eye = view.hand_from_camera.translation.vector;
        let centre_true = Point3::from(teleop_hand_model::scene::HAND_CENTRE_IN_HAND_FRAME);
        let to_eye = eye - centre_true.coords;
        let distance = to_eye.norm();
        let off_axis = (to_eye.y / distance.max(1e-9))
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees();
        let tip_error = retarget.tip_error_m.iter().sum::<f64>() / 5.0 * 1000.0;
        let meta = [
            distance as f32,
            off_axis as f32,
            hand.shape().scale as f32,
            pose_kind_id(&kind),
            human_fg as f32,
            robot_fg as f32,
            tip_error as f32,
            (attempt + 1) as f32,
        ];
        Ok(Ok(Sample {
            human,
            robot,
            joints,
            robot_uv,
            human_xyz,
            meta,
        }))
    }
}

impl Generator {
    /// The one preprocessing of the last rendered frame: the tensor and its
    /// foreground fraction, or why there is no hand in it.
    fn crop(
        &mut self,
        k: &Intrinsics,
        centre: &Point3<f64>,
    ) -> Result<Result<(Vec<f32>, f64), String>, DatasetError> {
        let mut out = vec![0.0f32; IMAGE_SIZE * IMAGE_SIZE];
        match preprocess(
            self.frame.depth_mm(),
            k,
            centre,
            &self.preprocess,
            &mut self.scratch,
            &mut out,
        )? {
            Crop::Hand { foreground } => Ok(Ok((out, foreground))),
            other => Ok(Err(format!("no hand in the crop ({other:?})"))),
        }
    }
}

fn pose_kind_id(kind: &PoseKind) -> f32 {
    match kind {
        PoseKind::Random => 0.0,
        PoseKind::Synergy { synergy, .. } => match synergy {
            Synergy::Open => 1.0,
            Synergy::Power => 2.0,
            Synergy::Precision => 3.0,
            Synergy::Pinch => 4.0,
            Synergy::Pointing => 5.0,
        },
        PoseKind::Blend { .. } => 6.0,
    }
}

/// SplitMix64-style mixing of seed, sample index and attempt.
fn mix(seed: u64, index: u64, attempt: u64) -> u64 {
    let mut z = seed
        ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ attempt.wrapping_mul(0xD1B5_4A32_D192_ED03);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// One shard in the manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardEntry {
    /// Directory relative to the dataset root.
    pub dir: String,
    /// First sample index and number of samples.
    pub first: usize,
    pub count: usize,
}

/// `manifest.json` at the dataset root.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub format: String,
    pub generator_version: u32,
    pub generator: String,
    pub config: GeneratorConfig,
    pub image_size: usize,
    pub cube_mm: f64,
    pub depth_normalisation: String,
    pub camera: CameraInfo,
    pub joint_names: Vec<String>,
    pub joint_lower: Vec<f64>,
    pub joint_upper: Vec<f64>,
    pub keypoint_names: Vec<String>,
    pub meta_columns: Vec<String>,
    pub pose_kinds: Vec<String>,
    /// File name -> description (dtype, shape, meaning).
    pub arrays: Vec<(String, String)>,
    pub shards: Vec<ShardEntry>,
}

/// The camera the images were rendered with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraInfo {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub range_m: [f64; 2],
    pub noise: String,
}

impl Manifest {
    fn new(config: &GeneratorConfig, g: &Generator) -> Self {
        let k = &g.intrinsics;
        let (lower, upper) = g.retargeter.limits();
        let n = IMAGE_SIZE;
        let arrays = [
            (
                "human.npy",
                format!("float16 [n, {n}, {n}]: preprocessed human depth, [-1, 1], background +1"),
            ),
            (
                "robot.npy",
                format!("float16 [n, {n}, {n}]: preprocessed Shadow depth, same crop, noise-free"),
            ),
            (
                "joints.npy",
                "float32 [n, 17]: Shadow finger joints (rad), joint_names order".to_owned(),
            ),
            (
                "robot_uv.npy",
                format!(
                    "float32 [n, 21, 2]: Shadow keypoints in crop pixels (u, v) of the {n} x {n} image"
                ),
            ),
            (
                "human_xyz.npy",
                "float32 [n, 21, 3]: human keypoints, camera frame (m)".to_owned(),
            ),
            ("meta.npy", "float32 [n, 8]: meta_columns".to_owned()),
        ];
        Self {
            format: FORMAT.to_owned(),
            generator_version: GENERATOR_VERSION,
            generator: format!("teleop-hand-dataset {}", env!("CARGO_PKG_VERSION")),
            config: config.clone(),
            image_size: n,
            cube_mm: g.preprocess.cube_mm,
            depth_normalisation: "(depth - centre depth) / (cube / 2), clamped to [-1, 1]; no return or outside the cube = +1".to_owned(),
            camera: CameraInfo {
                width: k.width(),
                height: k.height(),
                fx: k.fx(),
                fy: k.fy(),
                cx: k.cx(),
                cy: k.cy(),
                range_m: [g.range.min_m(), g.range.max_m()],
                noise: if config.noise { "SR300 (teleop-render NoiseParams::sr300), human image only".to_owned() } else { "none".to_owned() },
            },
            joint_names: SHADOW_FINGER_JOINTS.iter().map(|s| (*s).to_owned()).collect(),
            joint_lower: lower.to_vec(),
            joint_upper: upper.to_vec(),
            keypoint_names: KEYPOINT_NAMES.iter().map(|s| (*s).to_owned()).collect(),
            meta_columns: META_COLUMNS.iter().map(|s| (*s).to_owned()).collect(),
            pose_kinds: POSE_KINDS.iter().map(|s| (*s).to_owned()).collect(),
            arrays: arrays.into_iter().map(|(a, b)| (a.to_owned(), b)).collect(),
            shards: Vec::new(),
        }
    }

    /// Reads `root/manifest.json`.
    ///
    /// # Errors
    /// [`DatasetError::Io`] or [`DatasetError::Format`] (unknown fields included).
    pub fn read(root: &Path) -> Result<Self, DatasetError> {
        let path = root.join("manifest.json");
        let text = std::fs::read_to_string(&path).map_err(|source| DatasetError::Io {
            path: path.display().to_string(),
            source,
        })?;
        let m: Self = serde_json::from_str(&text).map_err(|e| DatasetError::Format {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        if m.format != FORMAT {
            return Err(DatasetError::Format {
                path: path.display().to_string(),
                reason: format!("format {:?}, expected {FORMAT:?}", m.format),
            });
        }
        Ok(m)
    }
}

/// Generates the set into `root` (created; must not already hold a manifest) with
/// `threads` workers; `progress` is called with the number of samples done.
///
/// # Errors
/// [`DatasetError::Io`] for file errors, [`DatasetError::Config`] for a bad config or
/// an existing dataset, or the first sample error.
pub fn generate(
    config: &GeneratorConfig,
    root: &Path,
    threads: usize,
    progress: &(dyn Fn(usize) + Sync),
) -> Result<Manifest, DatasetError> {
    config.validate()?;
    let io = |path: &Path| {
        let path = path.display().to_string();
        move |source| DatasetError::Io { path, source }
    };
    if root.join("manifest.json").exists() {
        return Err(DatasetError::Config(format!(
            "{} already holds a dataset (manifest.json); choose another directory",
            root.display()
        )));
    }
    std::fs::create_dir_all(root).map_err(io(root))?;
    let threads = threads.max(1);
    let mut generators = (0..threads)
        .map(|_| Generator::new(config.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let mut manifest = Manifest::new(config, &generators[0]);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let mut first = 0;
    let mut shard_index = 0;
    while first < config.count {
        let count = config.shard_size.min(config.count - first);
        let mut samples: Vec<Option<Sample>> = vec![None; count];
        let per = count.div_ceil(threads);
        let results: Vec<Result<(), DatasetError>> = std::thread::scope(|scope| {
            let handles: Vec<_> = samples
                .chunks_mut(per)
                .zip(generators.iter_mut())
                .enumerate()
                .map(|(t, (chunk, generator))| {
                    let done = &done;
                    scope.spawn(move || -> Result<(), DatasetError> {
                        for (j, slot) in chunk.iter_mut().enumerate() {
                            let index = (first + t * per + j) as u64;
                            *slot = Some(generator.sample(index)?);
                            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                            progress(n);
                        }
                        Ok(())
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join().unwrap_or_else(|_| {
                        Err(DatasetError::Config("a worker thread panicked".into()))
                    })
                })
                .collect()
        });
        for r in results {
            r?;
        }
        let samples: Vec<Sample> = samples.into_iter().flatten().collect();
        let dir_name = format!("shard_{shard_index:05}");
        let dir = root.join(&dir_name);
        std::fs::create_dir_all(&dir).map_err(io(&dir))?;
        write_shard(&dir, &samples)?;
        manifest.shards.push(ShardEntry {
            dir: dir_name,
            first,
            count,
        });
        first += count;
        shard_index += 1;
    }
    let path = root.join("manifest.json");
    let text = serde_json::to_string_pretty(&manifest).map_err(|e| DatasetError::Format {
        path: path.display().to_string(),
        reason: e.to_string(),
    })?;
    std::fs::write(&path, text).map_err(io(&path))?;
    Ok(manifest)
}

fn write_shard(dir: &Path, samples: &[Sample]) -> Result<(), DatasetError> {
    let n = samples.len();
    let s = IMAGE_SIZE;
    let cat = |f: &dyn Fn(&Sample) -> &[f32]| -> Vec<f32> {
        samples.iter().flat_map(|x| f(x).iter().copied()).collect()
    };
    npy::write(
        &dir.join("human.npy"),
        npy::Dtype::F16,
        &[n, s, s],
        &cat(&|x| &x.human),
    )?;
    npy::write(
        &dir.join("robot.npy"),
        npy::Dtype::F16,
        &[n, s, s],
        &cat(&|x| &x.robot),
    )?;
    npy::write(
        &dir.join("joints.npy"),
        npy::Dtype::F32,
        &[n, SHADOW_FINGER_DOF],
        &cat(&|x| &x.joints),
    )?;
    npy::write(
        &dir.join("robot_uv.npy"),
        npy::Dtype::F32,
        &[n, KEYPOINT_COUNT, 2],
        &cat(&|x| &x.robot_uv),
    )?;
    npy::write(
        &dir.join("human_xyz.npy"),
        npy::Dtype::F32,
        &[n, KEYPOINT_COUNT, 3],
        &cat(&|x| &x.human_xyz),
    )?;
    npy::write(
        &dir.join("meta.npy"),
        npy::Dtype::F32,
        &[n, META_COLUMNS.len()],
        &cat(&|x| &x.meta),
    )?;
    Ok(())
}

/// A whole dataset read back (for evaluation; training reads it with NumPy).
#[derive(Debug, Clone)]
pub struct Loaded {
    pub manifest: Manifest,
    /// `[n, IMAGE_SIZE^2]` flattened.
    pub human: Vec<f32>,
    pub robot: Vec<f32>,
    pub joints: Vec<f32>,
    pub meta: Vec<f32>,
    pub count: usize,
}

/// Reads every shard of the dataset at `root`.
///
/// # Errors
/// [`DatasetError`] for missing or malformed files, or shapes that disagree with the
/// manifest.
pub fn load(root: &Path) -> Result<Loaded, DatasetError> {
    let manifest = Manifest::read(root)?;
    let mut out = Loaded {
        human: Vec::new(),
        robot: Vec::new(),
        joints: Vec::new(),
        meta: Vec::new(),
        count: 0,
        manifest: manifest.clone(),
    };
    for shard in &manifest.shards {
        let dir: PathBuf = root.join(&shard.dir);
        let read = |name: &str, tail: &[usize]| -> Result<Vec<f32>, DatasetError> {
            let path = dir.join(name);
            let a = npy::read(&path)?;
            let mut expected = vec![shard.count];
            expected.extend_from_slice(tail);
            if a.shape != expected {
                return Err(DatasetError::Format {
                    path: path.display().to_string(),
                    reason: format!("shape {:?}, the manifest says {expected:?}", a.shape),
                });
            }
            Ok(a.data)
        };
        let s = manifest.image_size;
        out.human.extend(read("human.npy", &[s, s])?);
        out.robot.extend(read("robot.npy", &[s, s])?);
        out.joints.extend(read("joints.npy", &[SHADOW_FINGER_DOF])?);
        out.meta.extend(read("meta.npy", &[META_COLUMNS.len()])?);
        out.count += shard.count;
    }
    Ok(out)
}

//! Hand inference: a depth image and the hand-centre estimate in, the Shadow hand's
//! 17 finger joints out (thesis ch. 4-5).
//!
//! * [`HandEstimator`] preprocesses with the one preprocessing
//!   ([`teleop_hand_model::preprocess`], the dataset generator's), runs a
//!   [`JointModel`], checks and clamps its output, and answers
//!   [`HandEstimate::NoHand`] when the crop holds no hand — never made-up joints.
//! * [`OnnxModel`] runs an exported network with ONNX Runtime through `ort`, the
//!   library loaded at run time ([`runtime`]). The model's metadata must name the
//!   project's joints in order; its input is `depth` `[batch, 1, 96, 96]` float32 in
//!   `[-1, 1]`, its output `joints` `[batch, 17]` radians.
//! * [`DeterministicTestModel`] is a small model with the same interface, for tests
//!   of nodes built on this crate.
//! * [`metrics`]: the thesis's accuracy metrics.
//! * [`node`]: the `hand_inference` node (depth frames and the camera and wrist poses
//!   in, the finger joint targets out), generic over the [`JointModel`].

pub mod metrics;
pub mod node;
pub mod runtime;

use std::path::{Path, PathBuf};

use nalgebra::Point3;
use ort::session::Session;
use ort::value::TensorRef;
use teleop_hand_model::preprocess::{Crop, PreprocessConfig, Scratch, preprocess};
use teleop_hand_model::retarget::SHADOW_FINGER_DOF;
use teleop_interfaces::joints::SHADOW_FINGER_JOINTS;
use teleop_render::Intrinsics;

/// Input name of the exported networks.
pub const INPUT_NAME: &str = "depth";
/// Output name of the exported networks.
pub const OUTPUT_NAME: &str = "joints";

/// Errors of loading and running hand inference.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum InferenceError {
    #[error(
        "ONNX Runtime (libonnxruntime.so) not found; looked in: {}. Install it with `python3 -m pip install onnxruntime=={}` (bash tests/run.sh installs it into ~/.cache/teleop-venv), or set ORT_DYLIB_PATH or the node's onnxruntime_library to the library file",
        looked.join("; "),
        runtime::ONNXRUNTIME_VERSION
    )]
    RuntimeNotFound { looked: Vec<String> },
    #[error("ONNX Runtime: {0}")]
    RuntimeLoad(String),
    #[error("model {path}: {reason}")]
    Model { path: String, reason: String },
    #[error("inference failed: {0}")]
    Run(String),
    #[error("the model returned a non-finite value for {joint}")]
    NonFinite { joint: &'static str },
    #[error(transparent)]
    Input(#[from] teleop_hand_model::HandModelError),
    #[error("Shadow hand model: {0}")]
    ShadowModel(String),
}

/// A network from a preprocessed crop to joint angles.
pub trait JointModel: Send {
    /// Side of the square input the model takes.
    fn input_size(&self) -> usize;
    /// Joint angles (rad, [`SHADOW_FINGER_JOINTS`] order) for one preprocessed crop of
    /// `input_size()^2` values.
    ///
    /// # Errors
    /// [`InferenceError::Run`] if the model fails.
    fn infer(
        &mut self,
        input: &[f32],
        out: &mut [f32; SHADOW_FINGER_DOF],
    ) -> Result<(), InferenceError>;
}

/// An exported network run by ONNX Runtime.
#[derive(Debug)]
pub struct OnnxModel {
    session: Session,
    path: PathBuf,
    kind: String,
    size: usize,
    library: PathBuf,
}

/// Options of [`OnnxModel::load`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct OnnxOptions {
    /// `libonnxruntime.so` to use instead of searching ([`runtime`]).
    pub library: Option<PathBuf>,
    /// Intra-op threads (default 1: a node shares its machine with others).
    pub threads: Option<usize>,
}

impl OnnxModel {
    /// Loads `path` after checking its interface: input `depth` [batch, 1, S, S],
    /// output `joints` [batch, 17], metadata `teleop.joint_names` equal to the
    /// project's joint table.
    ///
    /// # Errors
    /// [`InferenceError::RuntimeNotFound`]/[`InferenceError::RuntimeLoad`] for the
    /// library, [`InferenceError::Model`] naming the file and what is wrong.
    pub fn load(path: &Path, options: &OnnxOptions) -> Result<Self, InferenceError> {
        let (env, library) = runtime::environment(options.library.as_deref())?;
        let model_err = |reason: String| InferenceError::Model {
            path: path.display().to_string(),
            reason,
        };
        if !path.is_file() {
            return Err(model_err("no such file".into()));
        }
        let threads = options.threads.unwrap_or(1).max(1);
        let session = Session::builder(env)
            .and_then(|b| b.with_intra_threads(threads).map_err(Into::into))
            .and_then(|b| b.with_inter_threads(1).map_err(Into::into))
            // Every graph optimisation, as Python onnxruntime applies by default.
            .and_then(|b| {
                b.with_optimization_level(ort::session::builder::GraphOptimizationLevel::All)
                    .map_err(Into::into)
            })
            .and_then(|mut b| b.commit_from_file(path))
            .map_err(|e| model_err(format!("cannot load: {e}")))?;
        let inputs = session.inputs();
        let outputs = session.outputs();
        if inputs.len() != 1 || inputs[0].name() != INPUT_NAME {
            return Err(model_err(format!(
                "expected one input named {INPUT_NAME:?}, found {:?}",
                inputs
                    .iter()
                    .map(ort::value::Outlet::name)
                    .collect::<Vec<_>>()
            )));
        }
        if outputs.is_empty() || outputs[0].name() != OUTPUT_NAME {
            return Err(model_err(format!(
                "expected the first output to be {OUTPUT_NAME:?}, found {:?}",
                outputs
                    .iter()
                    .map(ort::value::Outlet::name)
                    .collect::<Vec<_>>()
            )));
        }
        let shape: Vec<i64> = inputs[0]
            .dtype()
            .tensor_shape()
            .map(|s| s.iter().copied().collect())
            .unwrap_or_default();
        let size = match shape.as_slice() {
            [_, 1, h, w] if h == w && *h > 0 => *h as usize,
            other => {
                return Err(model_err(format!(
                    "input shape {other:?}, expected [batch, 1, S, S]"
                )));
            }
        };
        let out_shape: Vec<i64> = outputs[0]
            .dtype()
            .tensor_shape()
            .map(|s| s.iter().copied().collect())
            .unwrap_or_default();
        if out_shape.len() != 2 || out_shape[1] != SHADOW_FINGER_DOF as i64 {
            return Err(model_err(format!(
                "output shape {out_shape:?}, expected [batch, 17]"
            )));
        }
        let metadata = session
            .metadata()
            .map_err(|e| model_err(format!("no metadata: {e}")))?;
        let names = metadata
            .custom("teleop.joint_names")
            .ok_or_else(|| model_err("metadata teleop.joint_names is missing".into()))?;
        let names: Vec<&str> = names.split(',').collect();
        if names != SHADOW_FINGER_JOINTS {
            return Err(model_err(format!(
                "its joints {names:?} are not the project's {SHADOW_FINGER_JOINTS:?}"
            )));
        }
        let kind = metadata
            .custom("teleop.model")
            .unwrap_or_else(|| "unknown".into());
        drop(metadata);
        Ok(Self {
            session,
            path: path.to_path_buf(),
            kind,
            size,
            library: library.to_path_buf(),
        })
    }

    /// The network's kind from its metadata (`baseline`, `teachnet`, `transteleop`).
    #[must_use]
    pub fn kind(&self) -> &str {
        &self.kind
    }

    /// The model file.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The ONNX Runtime library in use.
    #[must_use]
    pub fn library(&self) -> &Path {
        &self.library
    }
}

impl JointModel for OnnxModel {
    fn input_size(&self) -> usize {
        self.size
    }

    fn infer(
        &mut self,
        input: &[f32],
        out: &mut [f32; SHADOW_FINGER_DOF],
    ) -> Result<(), InferenceError> {
        let s = self.size;
        if input.len() != s * s {
            return Err(InferenceError::Run(format!(
                "input holds {} values, the model takes {s} x {s}",
                input.len()
            )));
        }
        let tensor = TensorRef::from_array_view(([1usize, 1, s, s], input))
            .map_err(|e| InferenceError::Run(e.to_string()))?;
        let outputs = self
            .session
            .run(ort::inputs![INPUT_NAME => tensor])
            .map_err(|e| InferenceError::Run(e.to_string()))?;
        let (_, values) = outputs[OUTPUT_NAME]
            .try_extract_tensor::<f32>()
            .map_err(|e| InferenceError::Run(e.to_string()))?;
        if values.len() != SHADOW_FINGER_DOF {
            return Err(InferenceError::Run(format!(
                "the model returned {} values",
                values.len()
            )));
        }
        out.copy_from_slice(values);
        Ok(())
    }
}

/// A small deterministic model for tests of code built on [`JointModel`]: each joint is
/// its limits' midpoint moved by the mean of one horizontal band of the input (so a
/// changing image changes the joints), plus an optional fixed output override.
#[derive(Debug, Clone, PartialEq)]
pub struct DeterministicTestModel {
    pub size: usize,
    /// Returned as is when set (e.g. NaN to test the estimator's checks).
    pub fixed: Option<[f32; SHADOW_FINGER_DOF]>,
    /// Inferences run.
    pub calls: u64,
}

impl DeterministicTestModel {
    /// A model taking `size x size` crops.
    #[must_use]
    pub fn new(size: usize) -> Self {
        Self {
            size,
            fixed: None,
            calls: 0,
        }
    }
}

impl JointModel for DeterministicTestModel {
    fn input_size(&self) -> usize {
        self.size
    }

    fn infer(
        &mut self,
        input: &[f32],
        out: &mut [f32; SHADOW_FINGER_DOF],
    ) -> Result<(), InferenceError> {
        self.calls += 1;
        if let Some(f) = self.fixed {
            *out = f;
            return Ok(());
        }
        let rows = self.size.max(1);
        for (j, o) in out.iter_mut().enumerate() {
            let r0 = j * rows / SHADOW_FINGER_DOF;
            let r1 = ((j + 1) * rows / SHADOW_FINGER_DOF).max(r0 + 1);
            let band = &input[(r0 * self.size).min(input.len())..(r1 * self.size).min(input.len())];
            let mean = band.iter().sum::<f32>() / band.len().max(1) as f32;
            *o = 0.3 + 0.2 * mean;
        }
        Ok(())
    }
}

/// One estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HandEstimate {
    /// Joint angles (rad, [`SHADOW_FINGER_JOINTS`] order) within the Shadow's limits.
    Hand {
        joints: [f64; SHADOW_FINGER_DOF],
        /// Fraction of the crop that holds the hand.
        foreground: f64,
        /// Joints the estimator had to clamp into their limits.
        clamped: u32,
    },
    /// Too few hand pixels in the crop: no joints.
    NoHand { foreground: f64 },
}

/// Counters of an estimator.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EstimatorStats {
    pub frames: u64,
    pub hands: u64,
    pub no_hand: u64,
    pub clamped_joints: u64,
    pub rejected_non_finite: u64,
    pub errors: u64,
}

/// Preprocessing + model + output checks.
#[derive(Debug)]
pub struct HandEstimator<M: JointModel> {
    model: M,
    preprocess: PreprocessConfig,
    scratch: Scratch,
    input: Vec<f32>,
    lower: [f64; SHADOW_FINGER_DOF],
    upper: [f64; SHADOW_FINGER_DOF],
    stats: EstimatorStats,
}

impl<M: JointModel> HandEstimator<M> {
    /// An estimator with the default preprocessing (250 mm cube, the model's input
    /// size) and the Shadow's joint limits.
    ///
    /// # Errors
    /// [`InferenceError::ShadowModel`] only if the embedded Shadow model were broken.
    pub fn new(model: M) -> Result<Self, InferenceError> {
        let limits = teleop_hardware::safety::HandLimits::shadow()
            .map_err(|e| InferenceError::ShadowModel(e.to_string()))?;
        let (lower, upper) = (limits.lower_rad.into(), limits.upper_rad.into());
        let preprocess = PreprocessConfig {
            size: model.input_size(),
            ..PreprocessConfig::default()
        };
        Ok(Self {
            input: vec![0.0; preprocess.size * preprocess.size],
            model,
            preprocess,
            scratch: Scratch::default(),
            lower,
            upper,
            stats: EstimatorStats::default(),
        })
    }

    /// The model.
    pub fn model_mut(&mut self) -> &mut M {
        &mut self.model
    }

    /// Counters so far.
    #[must_use]
    pub fn stats(&self) -> EstimatorStats {
        self.stats
    }

    /// Estimates the joints from a depth image (`16UC1` mm, through `intrinsics`) and
    /// the hand-centre estimate (camera frame, m).
    ///
    /// # Errors
    /// [`InferenceError::Input`] for an image that does not match the intrinsics or a
    /// centre that is not finite or not in front of the camera;
    /// [`InferenceError::NonFinite`] if the model returned NaN or infinity;
    /// [`InferenceError::Run`] if it failed. Every error is counted.
    pub fn estimate(
        &mut self,
        depth_mm: &[u16],
        intrinsics: &Intrinsics,
        centre_m: &Point3<f64>,
    ) -> Result<HandEstimate, InferenceError> {
        self.stats.frames += 1;
        let crop = match preprocess(
            depth_mm,
            intrinsics,
            centre_m,
            &self.preprocess,
            &mut self.scratch,
            &mut self.input,
        ) {
            Ok(c) => c,
            Err(e) => {
                self.stats.errors += 1;
                return Err(e.into());
            }
        };
        match crop {
            Crop::NoHand { foreground } => {
                self.stats.no_hand += 1;
                Ok(HandEstimate::NoHand { foreground })
            }
            Crop::Hand { foreground } => self.run_model(foreground),
        }
    }

    /// Joints from an already preprocessed crop (evaluation on dataset tensors).
    ///
    /// # Errors
    /// As [`HandEstimator::estimate`].
    pub fn estimate_preprocessed(&mut self, input: &[f32]) -> Result<HandEstimate, InferenceError> {
        self.stats.frames += 1;
        if input.len() != self.input.len() {
            self.stats.errors += 1;
            return Err(InferenceError::Run(format!(
                "crop holds {} values, expected {}",
                input.len(),
                self.input.len()
            )));
        }
        self.input.copy_from_slice(input);
        let foreground = input.iter().filter(|v| **v < 1.0).count() as f64 / input.len() as f64;
        self.run_model(foreground)
    }

    fn run_model(&mut self, foreground: f64) -> Result<HandEstimate, InferenceError> {
        let mut raw = [0.0f32; SHADOW_FINGER_DOF];
        if let Err(e) = self.model.infer(&self.input, &mut raw) {
            self.stats.errors += 1;
            return Err(e);
        }
        let mut joints = [0.0; SHADOW_FINGER_DOF];
        let mut clamped = 0;
        for (i, v) in raw.iter().enumerate() {
            let v = f64::from(*v);
            if !v.is_finite() {
                self.stats.rejected_non_finite += 1;
                return Err(InferenceError::NonFinite {
                    joint: SHADOW_FINGER_JOINTS[i],
                });
            }
            let c = v.clamp(self.lower[i], self.upper[i]);
            if c != v {
                clamped += 1;
            }
            joints[i] = c;
        }
        self.stats.hands += 1;
        self.stats.clamped_joints += u64::from(clamped);
        Ok(HandEstimate::Hand {
            joints,
            foreground,
            clamped,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square_image(k: &Intrinsics, depth: u16, half: usize) -> Vec<u16> {
        let (w, h) = (k.width() as usize, k.height() as usize);
        let mut img = vec![0u16; w * h];
        for y in h / 2 - half..h / 2 + half {
            for x in w / 2 - half..w / 2 + half {
                img[y * w + x] = depth;
            }
        }
        img
    }

    #[test]
    fn an_empty_crop_is_no_hand_and_the_model_is_not_run() {
        let mut e = HandEstimator::new(DeterministicTestModel::new(96)).expect("estimator");
        let k = Intrinsics::sr300();
        let img = vec![0u16; (k.width() * k.height()) as usize];
        let r = e
            .estimate(&img, &k, &Point3::new(0.0, 0.0, 0.5))
            .expect("estimate");
        assert!(matches!(r, HandEstimate::NoHand { .. }));
        assert_eq!(e.model_mut().calls, 0);
        assert_eq!(e.stats().no_hand, 1);
    }

    #[test]
    fn joints_are_clamped_into_the_limits_and_nan_is_refused() {
        let mut model = DeterministicTestModel::new(96);
        model.fixed = Some([10.0; SHADOW_FINGER_DOF]);
        let mut e = HandEstimator::new(model).expect("estimator");
        let k = Intrinsics::sr300();
        let img = square_image(&k, 500, 60);
        let centre = Point3::new(0.0, 0.0, 0.5);
        match e.estimate(&img, &k, &centre).expect("estimate") {
            HandEstimate::Hand {
                joints, clamped, ..
            } => {
                assert_eq!(clamped, SHADOW_FINGER_DOF as u32);
                assert!(
                    joints
                        .iter()
                        .all(|j| *j <= std::f64::consts::FRAC_PI_2 + 1e-9)
                );
            }
            other => panic!("expected a hand, got {other:?}"),
        }
        let mut nan = [0.1f32; SHADOW_FINGER_DOF];
        nan[4] = f32::NAN;
        e.model_mut().fixed = Some(nan);
        let err = e.estimate(&img, &k, &centre).expect_err("NaN");
        assert!(err.to_string().contains(SHADOW_FINGER_JOINTS[4]), "{err}");
        assert_eq!(e.stats().rejected_non_finite, 1);
        // Bad input is an error, counted, and does not reach the model.
        let calls = e.model_mut().calls;
        assert!(e.estimate(&img[..10], &k, &centre).is_err());
        assert!(
            e.estimate(&img, &k, &Point3::new(0.0, 0.0, f64::NAN))
                .is_err()
        );
        assert_eq!(e.model_mut().calls, calls);
        assert_eq!(e.stats().errors, 2);
    }

    #[test]
    fn the_test_model_follows_its_input() {
        let mut m = DeterministicTestModel::new(96);
        let mut a = [0.0f32; SHADOW_FINGER_DOF];
        let mut b = [0.0f32; SHADOW_FINGER_DOF];
        m.infer(&vec![1.0; 96 * 96], &mut a).expect("a");
        m.infer(&vec![-0.5; 96 * 96], &mut b).expect("b");
        assert!(a.iter().zip(&b).all(|(x, y)| x > y));
    }
}

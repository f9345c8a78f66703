//! BigHand2.2M-style annotation files: one frame per line, the depth image's file name
//! then 63 numbers, the 21 keypoints' x y z in millimetres in the depth camera's frame,
//! in [`crate::KEYPOINT_NAMES`] order. Fields are separated by whitespace (tabs in the
//! original files). Blank lines and lines starting with `#` are skipped.
//!
//! With [`BIGHAND_INTRINSICS`] (the dataset's SR300) a user who owns the dataset can
//! project the keypoints into the images, take the hand centre for the crop
//! ([`hand_centre`]) and retarget the keypoints to Shadow joint labels — the same
//! pipeline the synthetic data runs through.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Point3;

use crate::HandModelError;
use crate::keypoints::{HandKeypoints, KEYPOINT_COUNT};

/// Focal lengths and principal point of the BigHand2.2M depth camera (Intel SR300,
/// 640 x 480), as published with the dataset: `(fx, fy, cx, cy)` in pixels.
pub const BIGHAND_INTRINSICS: (f64, f64, f64, f64) =
    (475.065948, 475.065857, 315.944855, 245.287079);

/// One annotated frame.
#[derive(Debug, Clone, PartialEq)]
pub struct AnnotatedFrame {
    /// The depth image's file name as written in the file.
    pub image: String,
    /// The 21 keypoints in metres, camera frame.
    pub keypoints: HandKeypoints,
}

/// Parses annotation text; `source` names it in errors.
///
/// # Errors
/// [`HandModelError::Annotation`] naming the line and what is wrong (missing image
/// name, wrong number of values, a value that is not a number or not finite).
pub fn parse(text: &str, source: &str) -> Result<Vec<AnnotatedFrame>, HandModelError> {
    let mut frames = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let err = |reason: String| HandModelError::Annotation {
            path: source.to_owned(),
            line: n + 1,
            reason,
        };
        let mut fields = trimmed.split_whitespace();
        let image = fields
            .next()
            .ok_or_else(|| err("missing the image name".into()))?;
        let mut values = [0.0_f64; KEYPOINT_COUNT * 3];
        let mut count = 0;
        for field in fields {
            if count == values.len() {
                return Err(err(format!(
                    "more than {} values after the image name",
                    values.len()
                )));
            }
            let v: f64 = field
                .parse()
                .map_err(|_| err(format!("value {} ({field:?}) is not a number", count + 1)))?;
            if !v.is_finite() {
                return Err(err(format!("value {} is not finite", count + 1)));
            }
            values[count] = v;
            count += 1;
        }
        if count != values.len() {
            return Err(err(format!(
                "{count} values after the image name, expected {} (21 keypoints x 3)",
                values.len()
            )));
        }
        let mut kp = [Point3::origin(); KEYPOINT_COUNT];
        for (i, p) in kp.iter_mut().enumerate() {
            *p = Point3::new(values[3 * i], values[3 * i + 1], values[3 * i + 2]) / 1000.0;
        }
        frames.push(AnnotatedFrame {
            image: image.to_owned(),
            keypoints: HandKeypoints(kp),
        });
    }
    Ok(frames)
}

/// Reads an annotation file.
///
/// # Errors
/// [`HandModelError::Io`] if it cannot be read, else as [`parse`].
pub fn read(path: &Path) -> Result<Vec<AnnotatedFrame>, HandModelError> {
    let text = std::fs::read_to_string(path).map_err(|source| HandModelError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse(&text, &path.display().to_string())
}

/// One annotation line (image name, tab, 63 values in mm with 4 decimals).
#[must_use]
pub fn format_line(frame: &AnnotatedFrame) -> String {
    let mut line = frame.image.clone();
    for p in &frame.keypoints.0 {
        for v in p.coords.iter() {
            let _ = write!(line, "\t{:.4}", v * 1000.0);
        }
    }
    line
}

/// Pixel coordinates `(u, v)` of a camera-frame point with the BigHand intrinsics, or
/// `None` behind the camera.
#[must_use]
pub fn project(p: &Point3<f64>) -> Option<(f64, f64)> {
    let (fx, fy, cx, cy) = BIGHAND_INTRINSICS;
    (p.z > 1e-6).then(|| (fx * p.x / p.z + cx, fy * p.y / p.z + cy))
}

/// The hand centre used for the crop: the mean of the wrist and the five MCPs (the
/// palm's middle), camera frame.
#[must_use]
pub fn hand_centre(kp: &HandKeypoints) -> Point3<f64> {
    let ids = [0usize, 1, 2, 3, 4, 5];
    let sum = ids
        .iter()
        .fold(nalgebra::Vector3::zeros(), |acc, i| acc + kp.0[*i].coords);
    Point3::from(sum / ids.len() as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(offset: f64) -> AnnotatedFrame {
        let mut kp = [Point3::origin(); KEYPOINT_COUNT];
        for (i, p) in kp.iter_mut().enumerate() {
            *p = Point3::new(0.01 * i as f64 + offset, -0.02, 0.4 + 0.001 * i as f64);
        }
        AnnotatedFrame {
            image: format!("image_D{:08}.png", (offset * 1000.0) as u32),
            keypoints: HandKeypoints(kp),
        }
    }

    #[test]
    fn lines_round_trip() {
        let frames = [frame(0.0), frame(0.005)];
        let text: String = frames.iter().map(|f| format_line(f) + "\n").collect();
        let parsed = parse(&format!("# header\n\n{text}"), "mem").expect("parse");
        assert_eq!(parsed.len(), 2);
        for (a, b) in parsed.iter().zip(&frames) {
            assert_eq!(a.image, b.image);
            assert!(a.keypoints.max_distance(&b.keypoints) < 1e-7);
        }
    }

    #[test]
    fn bad_lines_are_named() {
        let good = format_line(&frame(0.0));
        let short: String = good
            .rsplit_once('\t')
            .map(|x| x.0)
            .unwrap_or_default()
            .to_owned();
        let err = parse(&format!("{good}\n{short}\n"), "f.txt").expect_err("62 values");
        let msg = err.to_string();
        assert!(
            msg.contains("f.txt:2") && msg.contains("62 values"),
            "{msg}"
        );
        let err = parse(&format!("{good}\tx\n"), "f.txt").expect_err("64 values");
        assert!(err.to_string().contains("more than 63"), "{err}");
        let nan = good.replacen("\t", "\tnan ", 1);
        let err = parse(&nan, "f.txt").expect_err("nan");
        assert!(err.to_string().contains("f.txt:1"), "{err}");
        let word = good.replacen("\t", "\tabc\t", 1);
        assert!(parse(&word, "f.txt").is_err());
    }

    #[test]
    fn projection_uses_the_dataset_camera() {
        let (u, v) = project(&Point3::new(0.0, 0.0, 0.5)).expect("in front");
        assert!((u - BIGHAND_INTRINSICS.2).abs() < 1e-9 && (v - BIGHAND_INTRINSICS.3).abs() < 1e-9);
        assert!(project(&Point3::new(0.0, 0.0, -0.5)).is_none());
    }
}

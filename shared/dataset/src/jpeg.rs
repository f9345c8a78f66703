//! What a video file must know of a JPEG image without decoding it: its size and its
//! chroma subsampling, from the start-of-frame segment.

use crate::DatasetError;

/// A JPEG image's frame header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct JpegInfo {
    pub width: u16,
    pub height: u16,
    /// Colour components: 1 (grey) or 3 (YCbCr).
    pub components: u8,
    /// The pixel format FFmpeg gives the decoded image: `gray`, `yuvj420p`, `yuvj422p`,
    /// `yuvj444p` (or `other`).
    pub pix_fmt: &'static str,
}

/// Reads the frame header (SOF0-SOF3, SOF5-SOF7, SOF9-SOF11, SOF13-SOF15) of `bytes`.
///
/// # Errors
/// [`DatasetError::Jpeg`] naming what is wrong: no SOI marker, a segment running past
/// the end, no frame header before the scan.
pub fn jpeg_info(bytes: &[u8]) -> Result<JpegInfo, DatasetError> {
    let bad = |what: &str| DatasetError::Jpeg(what.to_owned());
    if bytes.get(..2) != Some(&[0xFF, 0xD8]) {
        return Err(bad("no start-of-image marker"));
    }
    let mut at = 2;
    loop {
        // Markers may be padded with 0xFF bytes.
        while bytes.get(at) == Some(&0xFF) && bytes.get(at + 1) == Some(&0xFF) {
            at += 1;
        }
        let (Some(&0xFF), Some(&marker)) = (bytes.get(at), bytes.get(at + 1)) else {
            return Err(bad("no frame header (SOF) before the end"));
        };
        at += 2;
        // Markers without a length.
        if (0xD0..=0xD7).contains(&marker) || marker == 0x01 {
            continue;
        }
        if marker == 0xD9 || marker == 0xDA {
            return Err(bad("no frame header (SOF) before the scan"));
        }
        let len = match bytes.get(at..at + 2) {
            Some(b) => usize::from(u16::from_be_bytes([b[0], b[1]])),
            None => return Err(bad("a segment's length runs past the end")),
        };
        if len < 2 {
            return Err(bad("a segment length below 2"));
        }
        let Some(seg) = bytes.get(at + 2..at + len) else {
            return Err(bad("a segment runs past the end"));
        };
        let is_sof = matches!(marker, 0xC0..=0xCF) && !matches!(marker, 0xC4 | 0xC8 | 0xCC);
        if is_sof {
            return sof(seg);
        }
        at += len;
    }
}

fn sof(seg: &[u8]) -> Result<JpegInfo, DatasetError> {
    let bad = |what: &str| DatasetError::Jpeg(what.to_owned());
    if seg.len() < 6 {
        return Err(bad("a frame header shorter than 6 bytes"));
    }
    let height = u16::from_be_bytes([seg[1], seg[2]]);
    let width = u16::from_be_bytes([seg[3], seg[4]]);
    let components = seg[5];
    if width == 0 || height == 0 {
        return Err(bad("a frame header with zero width or height"));
    }
    let comps = seg
        .get(6..6 + 3 * usize::from(components))
        .ok_or_else(|| bad("a frame header cut short in its components"))?;
    let sampling = |i: usize| (comps[3 * i + 1] >> 4, comps[3 * i + 1] & 0x0F);
    let pix_fmt = match components {
        1 => "gray",
        3 => {
            let (y, cb, cr) = (sampling(0), sampling(1), sampling(2));
            if cb != (1, 1) || cr != (1, 1) {
                "other"
            } else {
                match y {
                    (1, 1) => "yuvj444p",
                    (2, 1) => "yuvj422p",
                    (2, 2) => "yuvj420p",
                    _ => "other",
                }
            }
        }
        _ => "other",
    };
    Ok(JpegInfo {
        width,
        height,
        components,
        pix_fmt,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode(w: u32, h: u32) -> Vec<u8> {
        let img =
            image::RgbImage::from_fn(w, h, |x, y| image::Rgb([(x * 7) as u8, (y * 3) as u8, 90]));
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 80)
            .encode_image(&img)
            .expect("encode");
        out
    }

    #[test]
    fn the_frame_header_gives_size_and_subsampling() {
        let jpeg = encode(64, 48);
        let info = jpeg_info(&jpeg).expect("header");
        assert_eq!((info.width, info.height, info.components), (64, 48, 3));
        assert!(info.pix_fmt.starts_with("yuvj"), "{}", info.pix_fmt);
    }

    #[test]
    fn malformed_jpegs_are_named_never_panic() {
        let jpeg = encode(16, 16);
        assert!(jpeg_info(&[]).is_err());
        assert!(jpeg_info(b"PNG").is_err());
        for cut in 0..jpeg.len().min(700) {
            // Either a header or a clear error, for every prefix.
            let _ = jpeg_info(&jpeg[..cut]);
        }
        let err = jpeg_info(&jpeg[..4]).expect_err("cut");
        assert!(err.to_string().contains("JPEG"), "{err}");
        let mut zero = jpeg.clone();
        // Zero the width in the SOF0 segment.
        let sof = zero
            .windows(2)
            .position(|w| w == [0xFF, 0xC0])
            .expect("sof0");
        zero[sof + 7] = 0;
        zero[sof + 8] = 0;
        assert!(jpeg_info(&zero).is_err());
    }
}

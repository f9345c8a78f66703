//! Colour images to and from `sensor_msgs/CompressedImage` (JPEG), as ROS's
//! `image_transport` "compressed" transport carries them. The camera views cross the
//! WAN this way: a 320 x 240 `rgb8` view is 230 kB raw and a few kB as JPEG.
//!
//! Decoding takes bytes from the network: it never panics, refuses images larger than
//! [`MAX_PIXELS`] before allocating them, and names what was wrong.

use std::io::Cursor;

use crate::{CompressedImage, Image, encodings};

/// Largest side of an image [`decode_rgb8`] accepts, pixels.
pub const MAX_SIDE: u32 = 4096;
/// Largest image [`decode_rgb8`] accepts, pixels (4096 x 4096).
pub const MAX_PIXELS: u64 = MAX_SIDE as u64 * MAX_SIDE as u64;

/// What went wrong turning an image into JPEG or back.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[non_exhaustive]
pub enum ImageCodecError {
    #[error("JPEG quality must be in 1..=100, got {0}")]
    Quality(u8),
    #[error("only rgb8 images are compressed, got encoding `{0}`")]
    Encoding(String),
    #[error("image layout: {0}")]
    Layout(String),
    #[error("compressed image format `{0}` is not jpeg")]
    Format(String),
    #[error("image of {width} x {height} is larger than {MAX_PIXELS} pixels")]
    TooLarge { width: u32, height: u32 },
    #[error("JPEG: {0}")]
    Codec(String),
}

/// `image` as JPEG at `quality` (1-100), same header (stamp and frame), `format` "jpeg".
///
/// # Errors
/// A quality out of range, an encoding other than `rgb8`, an inconsistent layout.
pub fn jpeg_from_rgb8(image: &Image, quality: u8) -> Result<CompressedImage, ImageCodecError> {
    if !(1..=100).contains(&quality) {
        return Err(ImageCodecError::Quality(quality));
    }
    if image.encoding != encodings::RGB8 {
        return Err(ImageCodecError::Encoding(image.encoding.clone()));
    }
    image.check_layout().map_err(ImageCodecError::Layout)?;
    // Rows without their padding, if `step` has any.
    let row = image.width as usize * 3;
    let packed: std::borrow::Cow<'_, [u8]> = if image.step as usize == row {
        std::borrow::Cow::Borrowed(&image.data)
    } else {
        std::borrow::Cow::Owned(
            image
                .data
                .chunks(image.step as usize)
                .flat_map(|r| &r[..row])
                .copied()
                .collect(),
        )
    };
    let mut data = Vec::with_capacity(row * image.height as usize / 8);
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut data, quality)
        .encode(&packed, image.width, image.height, image::ColorType::Rgb8)
        .map_err(|e| ImageCodecError::Codec(e.to_string()))?;
    Ok(CompressedImage {
        header: image.header.clone(),
        format: "jpeg".into(),
        data,
    })
}

/// A JPEG `CompressedImage` back to an `rgb8` [`Image`] (same header).
///
/// # Errors
/// A format other than JPEG, bytes that are no JPEG, an image over [`MAX_PIXELS`].
pub fn decode_rgb8(compressed: &CompressedImage) -> Result<Image, ImageCodecError> {
    if compressed.codec() != Some("jpeg") {
        return Err(ImageCodecError::Format(compressed.format.clone()));
    }
    let mut reader =
        image::io::Reader::with_format(Cursor::new(&compressed.data), image::ImageFormat::Jpeg);
    let mut limits = image::io::Limits::default();
    limits.max_image_width = Some(MAX_SIDE);
    limits.max_image_height = Some(MAX_SIDE);
    limits.max_alloc = Some(MAX_PIXELS * 4);
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| match e {
        image::ImageError::Limits(_) => {
            let (width, height) = jpeg_size(&compressed.data).unwrap_or((u32::MAX, u32::MAX));
            ImageCodecError::TooLarge { width, height }
        }
        other => ImageCodecError::Codec(other.to_string()),
    })?;
    let rgb = decoded.to_rgb8();
    let (width, height) = rgb.dimensions();
    Ok(Image {
        header: compressed.header.clone(),
        height,
        width,
        encoding: encodings::RGB8.into(),
        is_bigendian: 0,
        step: width * 3,
        data: rgb.into_raw(),
    })
}

/// Width and height from a JPEG's frame header, if the bytes hold one.
fn jpeg_size(data: &[u8]) -> Option<(u32, u32)> {
    let mut i = 2;
    while i + 9 < data.len() {
        if data[i] != 0xff {
            return None;
        }
        let marker = data[i + 1];
        let len = usize::from(u16::from_be_bytes([data[i + 2], data[i + 3]]));
        if (0xc0..=0xcf).contains(&marker) && ![0xc4, 0xc8, 0xcc].contains(&marker) {
            let h = u16::from_be_bytes([data[i + 5], data[i + 6]]);
            let w = u16::from_be_bytes([data[i + 7], data[i + 8]]);
            return Some((u32::from(w), u32::from(h)));
        }
        i += 2 + len;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Header, Time};

    fn gradient(width: u32, height: u32, step: u32) -> Image {
        let mut data = vec![0u8; (step * height) as usize];
        for v in 0..height {
            for u in 0..width {
                let i = (v * step + u * 3) as usize;
                data[i] = (u * 255 / width) as u8;
                data[i + 1] = (v * 255 / height) as u8;
                data[i + 2] = 128;
            }
        }
        Image {
            header: Header::new(Time { sec: 3, nanosec: 4 }, "cam"),
            height,
            width,
            encoding: encodings::RGB8.into(),
            is_bigendian: 0,
            step,
            data,
        }
    }

    fn mean_abs_diff(a: &Image, b: &Image) -> f64 {
        let row = a.width as usize * 3;
        let mut sum = 0u64;
        for v in 0..a.height as usize {
            let ra = &a.data[v * a.step as usize..][..row];
            let rb = &b.data[v * b.step as usize..][..row];
            sum += ra
                .iter()
                .zip(rb)
                .map(|(x, y)| u64::from(x.abs_diff(*y)))
                .sum::<u64>();
        }
        sum as f64 / (row * a.height as usize) as f64
    }

    #[test]
    fn a_view_survives_jpeg_within_a_few_levels_and_is_much_smaller() {
        let img = gradient(320, 240, 320 * 3);
        let c = jpeg_from_rgb8(&img, 80).unwrap();
        assert_eq!(c.format, "jpeg");
        assert_eq!(c.header, img.header);
        assert!(c.data.len() * 10 < img.data.len(), "{} bytes", c.data.len());
        let back = decode_rgb8(&c).unwrap();
        assert_eq!((back.width, back.height, back.step), (320, 240, 960));
        assert_eq!(back.header, img.header);
        let d = mean_abs_diff(&img, &back);
        assert!(d < 3.0, "mean difference {d} levels");
    }

    #[test]
    fn padded_rows_are_packed_before_encoding() {
        let img = gradient(30, 20, 30 * 3 + 6);
        let back = decode_rgb8(&jpeg_from_rgb8(&img, 90).unwrap()).unwrap();
        assert_eq!(back.step, 90);
        assert!(mean_abs_diff(&img, &back) < 4.0);
    }

    #[test]
    fn bad_inputs_are_named() {
        let img = gradient(8, 8, 24);
        assert_eq!(
            jpeg_from_rgb8(&img, 0).unwrap_err(),
            ImageCodecError::Quality(0)
        );
        let depth = Image::depth_mm(Header::default(), 2, 1, &[1, 2]);
        assert_eq!(
            jpeg_from_rgb8(&depth, 80).unwrap_err(),
            ImageCodecError::Encoding("16UC1".into())
        );
        let mut short = img.clone();
        short.data.pop();
        assert!(matches!(
            jpeg_from_rgb8(&short, 80),
            Err(ImageCodecError::Layout(_))
        ));
        let png = CompressedImage {
            format: "png".into(),
            ..CompressedImage::default()
        };
        assert_eq!(
            decode_rgb8(&png).unwrap_err(),
            ImageCodecError::Format("png".into())
        );
        let junk = CompressedImage {
            format: "jpeg".into(),
            data: vec![0xff, 0xd8, 1, 2, 3],
            ..CompressedImage::default()
        };
        assert!(matches!(decode_rgb8(&junk), Err(ImageCodecError::Codec(_))));
        // image_transport's long form names the codec too.
        let mut long = jpeg_from_rgb8(&img, 80).unwrap();
        long.format = "rgb8; jpeg compressed bgr8".into();
        assert!(decode_rgb8(&long).is_ok());
    }

    #[test]
    fn a_huge_declared_size_is_refused_before_allocating() {
        // A valid small JPEG whose frame header is rewritten to claim 60000 x 60000.
        let mut c = jpeg_from_rgb8(&gradient(16, 16, 48), 80).unwrap();
        let sof = c.data.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
        c.data[sof + 5..sof + 9].copy_from_slice(&[0xea, 0x60, 0xea, 0x60]);
        assert_eq!(
            decode_rgb8(&c).unwrap_err(),
            ImageCodecError::TooLarge {
                width: 60000,
                height: 60000
            }
        );
    }
}

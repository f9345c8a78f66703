//! NumPy `.npy` files (format version 1.0), little-endian `float16` / `float32`
//! arrays in C order: what the dataset writes and what its reader and the evaluation
//! read back. `numpy.load` opens them directly.

use std::io::{Read, Write};
use std::path::Path;

use crate::DatasetError;

/// Element type of an array.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    F16,
    F32,
}

impl Dtype {
    fn descr(self) -> &'static str {
        match self {
            Dtype::F16 => "<f2",
            Dtype::F32 => "<f4",
        }
    }
    fn size(self) -> usize {
        match self {
            Dtype::F16 => 2,
            Dtype::F32 => 4,
        }
    }
}

/// Writes `data` (as f32 values, converted to `dtype`) with `shape` to `path`.
///
/// # Errors
/// [`DatasetError::Io`], or [`DatasetError::Format`] if the shape does not match.
pub fn write(path: &Path, dtype: Dtype, shape: &[usize], data: &[f32]) -> Result<(), DatasetError> {
    let count: usize = shape.iter().product();
    if count != data.len() {
        return Err(DatasetError::Format {
            path: path.display().to_string(),
            reason: format!("shape {shape:?} holds {count} values, got {}", data.len()),
        });
    }
    let dims: Vec<String> = shape.iter().map(ToString::to_string).collect();
    let shape_text = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!(
        "{{'descr': '{}', 'fortran_order': False, 'shape': {shape_text}, }}",
        dtype.descr()
    );
    // Magic (6) + version (2) + header length (2) + header + '\n', padded to 64.
    let unpadded = 10 + header.len() + 1;
    header.push_str(&" ".repeat((64 - unpadded % 64) % 64));
    header.push('\n');
    let mut bytes = Vec::with_capacity(10 + header.len() + data.len() * dtype.size());
    bytes.extend_from_slice(b"\x93NUMPY\x01\x00");
    let len = u16::try_from(header.len()).map_err(|_| DatasetError::Format {
        path: path.display().to_string(),
        reason: "header too long".into(),
    })?;
    bytes.extend_from_slice(&len.to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    match dtype {
        Dtype::F16 => {
            for v in data {
                bytes.extend_from_slice(&half::f16::from_f32(*v).to_le_bytes());
            }
        }
        Dtype::F32 => {
            for v in data {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    let io = |source| DatasetError::Io {
        path: path.display().to_string(),
        source,
    };
    let mut file = std::fs::File::create(path).map_err(io)?;
    file.write_all(&bytes).map_err(io)?;
    Ok(())
}

/// An array read back: shape and values as f32.
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    pub shape: Vec<usize>,
    pub data: Vec<f32>,
}

/// Reads a little-endian `float16` or `float32` C-order `.npy` file.
///
/// # Errors
/// [`DatasetError::Io`] or [`DatasetError::Format`] naming what is wrong.
pub fn read(path: &Path) -> Result<Array, DatasetError> {
    let name = path.display().to_string();
    let fmt = |reason: String| DatasetError::Format {
        path: name.clone(),
        reason,
    };
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .map_err(|source| DatasetError::Io {
            path: name.clone(),
            source,
        })?;
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(fmt("not a .npy file (bad magic)".into()));
    }
    let (header_len, start) = match bytes[6] {
        1 => (usize::from(u16::from_le_bytes([bytes[8], bytes[9]])), 10),
        2 | 3 if bytes.len() >= 12 => (
            u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
            12,
        ),
        v => return Err(fmt(format!("unsupported .npy version {v}"))),
    };
    let header = bytes
        .get(start..start + header_len)
        .and_then(|h| std::str::from_utf8(h).ok())
        .ok_or_else(|| fmt("truncated or non-UTF-8 header".into()))?;
    let dtype = if header.contains("'<f2'") {
        Dtype::F16
    } else if header.contains("'<f4'") {
        Dtype::F32
    } else {
        return Err(fmt(format!("unsupported dtype in header {header:?}")));
    };
    if header.contains("'fortran_order': True") {
        return Err(fmt("Fortran-order arrays are not supported".into()));
    }
    let shape_text = header
        .split("'shape':")
        .nth(1)
        .and_then(|s| s.split('(').nth(1))
        .and_then(|s| s.split(')').next())
        .ok_or_else(|| fmt("no shape in header".into()))?;
    let shape: Vec<usize> = shape_text
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().map_err(|_| fmt(format!("bad shape entry {s:?}"))))
        .collect::<Result<_, _>>()?;
    let count: usize = shape.iter().product();
    let body = &bytes[start + header_len..];
    if body.len() != count * dtype.size() {
        return Err(fmt(format!(
            "shape {shape:?} needs {} bytes of data, the file has {}",
            count * dtype.size(),
            body.len()
        )));
    }
    let data = match dtype {
        Dtype::F16 => body
            .chunks_exact(2)
            .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
            .collect(),
        Dtype::F32 => body
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
    };
    Ok(Array { shape, data })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrays_round_trip_and_headers_are_aligned() {
        let dir = std::env::temp_dir().join(format!("npy-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.25 - 3.0).collect();
        for dtype in [Dtype::F16, Dtype::F32] {
            let path = dir.join(format!("{dtype:?}.npy"));
            write(&path, dtype, &[2, 3, 4], &data).expect("write");
            let bytes = std::fs::read(&path).expect("bytes");
            let header_len = usize::from(u16::from_le_bytes([bytes[8], bytes[9]]));
            assert_eq!((10 + header_len) % 64, 0);
            let back = read(&path).expect("read");
            assert_eq!(back.shape, vec![2, 3, 4]);
            assert_eq!(
                back.data, data,
                "exact in f16 too: quarters are representable"
            );
        }
        let path = dir.join("one.npy");
        write(&path, Dtype::F32, &[3], &[1.0, 2.0, 3.0]).expect("1-d");
        assert_eq!(read(&path).expect("read").shape, vec![3]);
        assert!(write(&path, Dtype::F32, &[2, 2], &[1.0]).is_err());
        std::fs::write(&path, b"garbage").expect("write");
        let err = read(&path).expect_err("garbage");
        assert!(err.to_string().contains("magic"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}

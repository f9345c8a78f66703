//! MP4 files of JPEG samples (Motion JPEG, ISO/IEC 14496-12 with the `mp4v` sample
//! entry and object type 0x6C, as FFmpeg writes `-c:v mjpeg` into `.mp4`).
//!
//! The camera views already travel as JPEG, so a video file of them needs no encoder:
//! each view becomes one sample, unchanged. Every sample lasts one frame at the file's
//! frame rate (time scale = fps, duration 1), so frame `k` is presented at exactly
//! `k / fps` s, what LeRobot's decoders look up.
//!
//! The writer streams: `ftyp`, then an `mdat` whose 64-bit size is filled in at the
//! end, then `moov` with the sample tables.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use crate::DatasetError;
use crate::jpeg::{JpegInfo, jpeg_info};

/// Writes one MJPEG MP4 file, sample by sample.
#[derive(Debug)]
pub struct MjpegMp4Writer {
    path: PathBuf,
    out: BufWriter<File>,
    fps: u32,
    /// Where the `mdat` box starts.
    mdat_at: u64,
    /// Where the next sample goes.
    at: u64,
    sizes: Vec<u32>,
    offsets: Vec<u64>,
    info: Option<JpegInfo>,
}

impl MjpegMp4Writer {
    /// Creates `path` (overwriting) for frames at `fps`.
    ///
    /// # Errors
    /// [`DatasetError::Io`]; [`DatasetError::Config`] for `fps` 0.
    pub fn create(path: &Path, fps: u32) -> Result<Self, DatasetError> {
        if fps == 0 {
            return Err(DatasetError::Config("fps must be positive".to_owned()));
        }
        let io = |e| DatasetError::io(path, e);
        let mut out = BufWriter::new(File::create(path).map_err(io)?);
        let mut ftyp = Vec::new();
        ftyp.extend_from_slice(b"isom");
        ftyp.extend_from_slice(&512u32.to_be_bytes());
        for brand in [b"isom", b"iso2", b"mp41"] {
            ftyp.extend_from_slice(brand);
        }
        let ftyp = boxed(*b"ftyp", &ftyp);
        out.write_all(&ftyp).map_err(io)?;
        let mdat_at = ftyp.len() as u64;
        // Large-size mdat header: size 1, type, 64-bit size (filled in at the end).
        out.write_all(&1u32.to_be_bytes()).map_err(io)?;
        out.write_all(b"mdat").map_err(io)?;
        out.write_all(&0u64.to_be_bytes()).map_err(io)?;
        Ok(Self {
            path: path.to_owned(),
            out,
            fps,
            mdat_at,
            at: mdat_at + 16,
            sizes: Vec::new(),
            offsets: Vec::new(),
            info: None,
        })
    }

    /// Appends one frame (a whole JPEG image). Every frame of a file must have the
    /// first one's size and pixel format.
    ///
    /// # Errors
    /// [`DatasetError::Jpeg`] for a malformed image, [`DatasetError::Video`] for one of
    /// another size or format, [`DatasetError::Io`].
    pub fn push(&mut self, jpeg: &[u8]) -> Result<(), DatasetError> {
        let info = jpeg_info(jpeg)?;
        match self.info {
            None => self.info = Some(info),
            Some(first) if first != info => {
                return Err(DatasetError::Video(format!(
                    "{}: frame {} is {}x{} {}, the file's first frame {}x{} {}",
                    self.path.display(),
                    self.sizes.len(),
                    info.width,
                    info.height,
                    info.pix_fmt,
                    first.width,
                    first.height,
                    first.pix_fmt
                )));
            }
            Some(_) => {}
        }
        let size = u32::try_from(jpeg.len())
            .map_err(|_| DatasetError::Video("a JPEG frame over 4 GiB".to_owned()))?;
        self.out
            .write_all(jpeg)
            .map_err(|e| DatasetError::io(&self.path, e))?;
        self.offsets.push(self.at);
        self.sizes.push(size);
        self.at += u64::from(size);
        Ok(())
    }

    /// Frames written so far.
    #[must_use]
    pub fn frames(&self) -> usize {
        self.sizes.len()
    }

    /// Bytes written so far (samples and headers, not yet the sample tables).
    #[must_use]
    pub fn bytes(&self) -> u64 {
        self.at
    }

    /// The first frame's header, if any frame was written.
    #[must_use]
    pub fn info(&self) -> Option<JpegInfo> {
        self.info
    }

    /// Writes the sample tables and closes the file.
    ///
    /// # Errors
    /// [`DatasetError::Video`] for a file without frames, [`DatasetError::Io`].
    pub fn finish(mut self) -> Result<(), DatasetError> {
        let info = self.info.ok_or_else(|| {
            DatasetError::Video(format!("{}: a video without frames", self.path.display()))
        })?;
        let io = |e| DatasetError::io(&self.path, e);
        let moov = self.moov(info);
        self.out.write_all(&moov).map_err(io)?;
        let mut file = self.out.into_inner().map_err(|e| io(e.into_error()))?;
        file.seek(SeekFrom::Start(self.mdat_at + 8)).map_err(io)?;
        file.write_all(&(self.at - self.mdat_at).to_be_bytes())
            .map_err(io)?;
        file.sync_all().map_err(io)?;
        Ok(())
    }

    fn moov(&self, info: JpegInfo) -> Vec<u8> {
        let n = u32::try_from(self.sizes.len()).unwrap_or(u32::MAX);
        // Movie time scale 1000 (ms); the track's is the frame rate.
        let movie_duration = u64::from(n) * 1000 / u64::from(self.fps);
        let movie_duration = u32::try_from(movie_duration).unwrap_or(u32::MAX);
        let (w, h) = (u32::from(info.width), u32::from(info.height));

        let mut mvhd = full(0, 0);
        mvhd.extend_from_slice(&[0; 8]); // creation, modification
        mvhd.extend_from_slice(&1000u32.to_be_bytes());
        mvhd.extend_from_slice(&movie_duration.to_be_bytes());
        mvhd.extend_from_slice(&0x0001_0000u32.to_be_bytes()); // rate 1.0
        mvhd.extend_from_slice(&0x0100u16.to_be_bytes()); // volume 1.0
        mvhd.extend_from_slice(&[0; 10]);
        mvhd.extend_from_slice(&MATRIX);
        mvhd.extend_from_slice(&[0; 24]);
        mvhd.extend_from_slice(&2u32.to_be_bytes()); // next track id

        let mut tkhd = full(0, 3); // enabled, in movie
        tkhd.extend_from_slice(&[0; 8]);
        tkhd.extend_from_slice(&1u32.to_be_bytes()); // track id
        tkhd.extend_from_slice(&[0; 4]);
        tkhd.extend_from_slice(&movie_duration.to_be_bytes());
        tkhd.extend_from_slice(&[0; 8]);
        tkhd.extend_from_slice(&[0; 4]); // layer, alternate group
        tkhd.extend_from_slice(&[0; 4]); // volume, reserved
        tkhd.extend_from_slice(&MATRIX);
        tkhd.extend_from_slice(&(w << 16).to_be_bytes());
        tkhd.extend_from_slice(&(h << 16).to_be_bytes());

        let mut mdhd = full(0, 0);
        mdhd.extend_from_slice(&[0; 8]);
        mdhd.extend_from_slice(&self.fps.to_be_bytes());
        mdhd.extend_from_slice(&n.to_be_bytes());
        mdhd.extend_from_slice(&0x55C4u16.to_be_bytes()); // "und"
        mdhd.extend_from_slice(&[0; 2]);

        let mut hdlr = full(0, 0);
        hdlr.extend_from_slice(&[0; 4]);
        hdlr.extend_from_slice(b"vide");
        hdlr.extend_from_slice(&[0; 12]);
        hdlr.extend_from_slice(b"VideoHandler\0");

        let mut vmhd = full(0, 1);
        vmhd.extend_from_slice(&[0; 8]);

        let mut dref = full(0, 0);
        dref.extend_from_slice(&1u32.to_be_bytes());
        dref.extend_from_slice(&boxed(*b"url ", &full(0, 1)));
        let dinf = boxed(*b"dinf", &boxed(*b"dref", &dref));

        let mut stsd = full(0, 0);
        stsd.extend_from_slice(&1u32.to_be_bytes());
        stsd.extend_from_slice(&self.sample_entry(info));

        let mut stts = full(0, 0);
        stts.extend_from_slice(&1u32.to_be_bytes());
        stts.extend_from_slice(&n.to_be_bytes());
        stts.extend_from_slice(&1u32.to_be_bytes());

        // One sample per chunk.
        let mut stsc = full(0, 0);
        stsc.extend_from_slice(&1u32.to_be_bytes());
        for v in [1u32, 1, 1] {
            stsc.extend_from_slice(&v.to_be_bytes());
        }

        let mut stsz = full(0, 0);
        stsz.extend_from_slice(&0u32.to_be_bytes());
        stsz.extend_from_slice(&n.to_be_bytes());
        for s in &self.sizes {
            stsz.extend_from_slice(&s.to_be_bytes());
        }

        let mut co64 = full(0, 0);
        co64.extend_from_slice(&n.to_be_bytes());
        for o in &self.offsets {
            co64.extend_from_slice(&o.to_be_bytes());
        }

        let stbl = [
            boxed(*b"stsd", &stsd),
            boxed(*b"stts", &stts),
            boxed(*b"stsc", &stsc),
            boxed(*b"stsz", &stsz),
            boxed(*b"co64", &co64),
        ]
        .concat();
        let minf = [boxed(*b"vmhd", &vmhd), dinf, boxed(*b"stbl", &stbl)].concat();
        let mdia = [
            boxed(*b"mdhd", &mdhd),
            boxed(*b"hdlr", &hdlr),
            boxed(*b"minf", &minf),
        ]
        .concat();
        let trak = [boxed(*b"tkhd", &tkhd), boxed(*b"mdia", &mdia)].concat();
        let moov = [boxed(*b"mvhd", &mvhd), boxed(*b"trak", &trak)].concat();
        boxed(*b"moov", &moov)
    }

    /// The `mp4v` visual sample entry with an `esds` naming JPEG (object type 0x6C).
    fn sample_entry(&self, info: JpegInfo) -> Vec<u8> {
        let mut e = Vec::new();
        e.extend_from_slice(&[0; 6]);
        e.extend_from_slice(&1u16.to_be_bytes()); // data reference index
        e.extend_from_slice(&[0; 16]);
        e.extend_from_slice(&info.width.to_be_bytes());
        e.extend_from_slice(&info.height.to_be_bytes());
        e.extend_from_slice(&0x0048_0000u32.to_be_bytes()); // 72 dpi
        e.extend_from_slice(&0x0048_0000u32.to_be_bytes());
        e.extend_from_slice(&[0; 4]);
        e.extend_from_slice(&1u16.to_be_bytes()); // frames per sample
        let mut name = [0u8; 32];
        let label = b"teleop mjpeg";
        name[0] = label.len() as u8;
        name[1..=label.len()].copy_from_slice(label);
        e.extend_from_slice(&name);
        e.extend_from_slice(&0x0018u16.to_be_bytes()); // depth
        e.extend_from_slice(&(-1i16).to_be_bytes());

        let largest = self.sizes.iter().copied().max().unwrap_or(0);
        let total: u64 = self.sizes.iter().map(|&s| u64::from(s)).sum();
        let seconds = (self.sizes.len() as f64 / f64::from(self.fps)).max(1e-9);
        let avg_bitrate = u32::try_from((total as f64 * 8.0 / seconds) as u64).unwrap_or(u32::MAX);
        let mut dcd = vec![0x6C, (0x04 << 2) | 1];
        dcd.extend_from_slice(&largest.to_be_bytes()[1..]); // buffer size, 24 bits
        dcd.extend_from_slice(&avg_bitrate.to_be_bytes()); // max bitrate
        dcd.extend_from_slice(&avg_bitrate.to_be_bytes());
        let mut es = vec![0, 1, 0]; // ES id 1, no flags
        es.extend_from_slice(&descriptor(0x04, &dcd));
        es.extend_from_slice(&descriptor(0x06, &[0x02]));
        let mut esds = full(0, 0);
        esds.extend_from_slice(&descriptor(0x03, &es));
        e.extend_from_slice(&boxed(*b"esds", &esds));
        boxed(*b"mp4v", &e)
    }
}

const MATRIX: [u8; 36] = [
    0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, //
    0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, //
    0, 0, 0, 0, 0, 0, 0, 0, 0x40, 0, 0, 0,
];

fn boxed(kind: [u8; 4], body: &[u8]) -> Vec<u8> {
    let size = u32::try_from(body.len() + 8).unwrap_or(u32::MAX);
    let mut b = Vec::with_capacity(body.len() + 8);
    b.extend_from_slice(&size.to_be_bytes());
    b.extend_from_slice(&kind);
    b.extend_from_slice(body);
    b
}

fn full(version: u8, flags: u32) -> Vec<u8> {
    let f = flags.to_be_bytes();
    vec![version, f[1], f[2], f[3]]
}

/// An MPEG-4 descriptor with its length in the 4-byte form (valid for any length
/// below 2^28).
fn descriptor(tag: u8, body: &[u8]) -> Vec<u8> {
    let len = u32::try_from(body.len()).unwrap_or(0);
    let mut d = vec![
        tag,
        0x80 | ((len >> 21) & 0x7F) as u8,
        0x80 | ((len >> 14) & 0x7F) as u8,
        0x80 | ((len >> 7) & 0x7F) as u8,
        (len & 0x7F) as u8,
    ];
    d.extend_from_slice(body);
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn jpeg(w: u32, h: u32, shade: u8) -> Vec<u8> {
        let img = image::RgbImage::from_pixel(w, h, image::Rgb([shade, 128, 64]));
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 90)
            .encode_image(&img)
            .expect("encode");
        out
    }

    /// Walks the boxes of `buf[from..to]`: (type, start of body, end).
    fn boxes(buf: &[u8], from: usize, to: usize) -> Vec<([u8; 4], usize, usize)> {
        let mut out = Vec::new();
        let mut at = from;
        while at + 8 <= to {
            let size = u32::from_be_bytes(buf[at..at + 4].try_into().expect("4")) as usize;
            let kind: [u8; 4] = buf[at + 4..at + 8].try_into().expect("4");
            let (body, end) = if size == 1 {
                let big = u64::from_be_bytes(buf[at + 8..at + 16].try_into().expect("8"));
                (at + 16, at + big as usize)
            } else {
                (at + 8, at + size)
            };
            out.push((kind, body, end));
            at = end;
        }
        out
    }

    #[test]
    fn samples_are_stored_unchanged_and_indexed() {
        let dir = std::env::temp_dir().join(format!("teleop-mp4-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("v.mp4");
        let frames: Vec<Vec<u8>> = (0..5).map(|i| jpeg(32, 24, 40 * i)).collect();
        let mut w = MjpegMp4Writer::create(&path, 30).expect("create");
        for f in &frames {
            w.push(f).expect("push");
        }
        assert!(w.push(&jpeg(16, 24, 0)).is_err(), "another size is refused");
        assert_eq!(w.frames(), 5);
        w.finish().expect("finish");
        let buf = std::fs::read(&path).expect("read");
        let top = boxes(&buf, 0, buf.len());
        let kinds: Vec<_> = top.iter().map(|b| b.0).collect();
        assert_eq!(kinds, vec![*b"ftyp", *b"mdat", *b"moov"]);
        assert_eq!(
            top.last().expect("moov").2,
            buf.len(),
            "boxes tile the file"
        );
        // Find the sample tables.
        let mut stack = vec![(top[2].1, top[2].2)];
        let mut found = std::collections::HashMap::new();
        while let Some((a, b)) = stack.pop() {
            for (k, s, e) in boxes(&buf, a, b) {
                found.insert(k, (s, e));
                if [*b"trak", *b"mdia", *b"minf", *b"stbl"].contains(&k) {
                    stack.push((s, e));
                }
            }
        }
        let (s, _) = found[b"co64"];
        let n = u32::from_be_bytes(buf[s + 4..s + 8].try_into().expect("4")) as usize;
        assert_eq!(n, 5);
        let (z, _) = found[b"stsz"];
        for (i, f) in frames.iter().enumerate() {
            let off = u64::from_be_bytes(buf[s + 8 + 8 * i..s + 16 + 8 * i].try_into().expect("8"));
            let size =
                u32::from_be_bytes(buf[z + 12 + 4 * i..z + 16 + 4 * i].try_into().expect("4"));
            assert_eq!(
                &buf[off as usize..off as usize + size as usize],
                f.as_slice()
            );
        }
        let (m, _) = found[b"mdhd"];
        assert_eq!(
            u32::from_be_bytes(buf[m + 12..m + 16].try_into().expect("4")),
            30
        );
        assert_eq!(
            u32::from_be_bytes(buf[m + 16..m + 20].try_into().expect("4")),
            5
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_video_without_frames_or_fps_is_refused() {
        let dir = std::env::temp_dir().join(format!("teleop-mp4e-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        assert!(MjpegMp4Writer::create(&dir.join("a.mp4"), 0).is_err());
        let w = MjpegMp4Writer::create(&dir.join("b.mp4"), 10).expect("create");
        assert!(w.finish().is_err());
        let mut w = MjpegMp4Writer::create(&dir.join("c.mp4"), 10).expect("create");
        assert!(w.push(b"not a jpeg").is_err());
        std::fs::remove_dir_all(&dir).ok();
    }
}

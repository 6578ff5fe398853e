//! Depth streams of the DexJoCo raw layout: `videos/<camera>_depth.npz`, key `depth`,
//! float32 (T, H, W) in metres, as `numpy.savez_compressed` writes it (one deflated
//! `depth.npy` member).
//!
//! [`DepthWriter`] streams frames into the archive one at a time (never a whole episode
//! in memory) and renames the finished file into place; [`read_depth_npz`] reads one back,
//! [`for_each_depth_frame`] streams its frames, [`depth_npz_shape`] reads its shape.

use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use crate::error::io_err;
use crate::error::{FormatError, Result};

/// The array name inside the archive.
pub const DEPTH_KEY: &str = "depth";

/// The `.npy` header of a little-endian float32 C-order array of `shape` (format 1.0,
/// padded so the data starts at a multiple of 64 bytes).
fn npy_header(shape: &[usize]) -> Vec<u8> {
    let dims = match shape {
        [one] => format!("({one},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut dict = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {dims}, }}");
    // magic (6) + version (2) + length (2) + dict + '\n' is a multiple of 64.
    while (10 + dict.len() + 1) % 64 != 0 {
        dict.push(' ');
    }
    dict.push('\n');
    let mut h = Vec::with_capacity(10 + dict.len());
    h.extend_from_slice(b"\x93NUMPY\x01\x00");
    h.extend_from_slice(
        &u16::try_from(dict.len())
            .expect("short header")
            .to_le_bytes(),
    );
    h.extend_from_slice(dict.as_bytes());
    h
}

/// Streams depth frames into `<camera>_depth.npz`.
pub struct DepthWriter {
    zip: zip::ZipWriter<BufWriter<fs_err::File>>,
    tmp: PathBuf,
    path: PathBuf,
    frames: usize,
    pixels: usize,
    written: usize,
}

impl DepthWriter {
    /// Starts the archive for `frames` frames of `width` x `height` (the array's shape is
    /// in its header, so the count is fixed up front); written to a temporary name.
    pub fn create(
        path: impl Into<PathBuf>,
        frames: usize,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        let path = path.into();
        let tmp = path.with_extension("npz.tmp");
        let file = fs_err::File::create(&tmp).map_err(io_err("create", &tmp))?;
        let mut zip = zip::ZipWriter::new(BufWriter::new(file));
        let (w, h) = (width as usize, height as usize);
        let bytes = frames * w * h * 4 + 128;
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .compression_level(Some(1))
            .large_file(bytes > u32::MAX as usize);
        let zip_err = |e: zip::result::ZipError| FormatError::Io {
            op: "write",
            path: tmp.clone(),
            source: std::io::Error::other(e),
        };
        zip.start_file(format!("{DEPTH_KEY}.npy"), options)
            .map_err(zip_err)?;
        zip.write_all(&npy_header(&[frames, h, w]))
            .map_err(io_err("write", &tmp))?;
        Ok(Self {
            zip,
            tmp,
            path,
            frames,
            pixels: w * h,
            written: 0,
        })
    }

    /// Appends one frame (row-major, top row first, metres).
    pub fn write_frame(&mut self, depth: &[f32]) -> Result<()> {
        if depth.len() != self.pixels || self.written == self.frames {
            return Err(FormatError::Io {
                op: "write",
                path: self.tmp.clone(),
                source: std::io::Error::other(format!(
                    "depth frame {} has {} values; expected {} and at most {} frames",
                    self.written,
                    depth.len(),
                    self.pixels,
                    self.frames
                )),
            });
        }
        let mut buf = Vec::with_capacity(depth.len() * 4);
        for v in depth {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        self.zip
            .write_all(&buf)
            .map_err(io_err("write", &self.tmp))?;
        self.written += 1;
        Ok(())
    }

    /// Finishes the archive (every announced frame must have been written) and renames
    /// it into place.
    pub fn finish(self) -> Result<PathBuf> {
        if self.written != self.frames {
            return Err(FormatError::Io {
                op: "finish",
                path: self.tmp.clone(),
                source: std::io::Error::other(format!(
                    "{} of {} depth frames written",
                    self.written, self.frames
                )),
            });
        }
        let tmp = self.tmp;
        let file = self
            .zip
            .finish()
            .map_err(|e| FormatError::Io {
                op: "finish",
                path: tmp.clone(),
                source: std::io::Error::other(e),
            })?
            .into_inner()
            .map_err(|e| FormatError::Io {
                op: "flush",
                path: tmp.clone(),
                source: e.into_error(),
            })?;
        file.sync_all().map_err(io_err("sync", &tmp))?;
        fs_err::rename(&tmp, &self.path).map_err(io_err("rename", &tmp))?;
        Ok(self.path)
    }
}

/// An invalid-data error on `path`.
fn invalid(path: &Path, what: String) -> FormatError {
    FormatError::Io {
        op: "read",
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, what),
    }
}

/// Reads the `.npy` header of the `depth` member from `r`: the (T, H, W) shape.
fn read_header(r: &mut impl Read, path: &Path) -> Result<(usize, usize, usize)> {
    let mut pre = [0u8; 10];
    r.read_exact(&mut pre)
        .map_err(|_| invalid(path, "not an .npy (format 1.0) member".into()))?;
    if &pre[..8] != b"\x93NUMPY\x01\x00" {
        return Err(invalid(path, "not an .npy (format 1.0) member".into()));
    }
    let mut header = vec![0u8; u16::from_le_bytes([pre[8], pre[9]]) as usize];
    r.read_exact(&mut header)
        .map_err(|_| invalid(path, "short header".into()))?;
    let header = String::from_utf8(header).map_err(|e| invalid(path, e.to_string()))?;
    if !header.contains("'descr': '<f4'") || !header.contains("'fortran_order': False") {
        return Err(invalid(
            path,
            format!("expected little-endian float32 in C order, found {header}"),
        ));
    }
    let dims: Vec<usize> = header
        .split("'shape': (")
        .nth(1)
        .and_then(|s| s.split(')').next())
        .map(|s| s.split(',').filter_map(|d| d.trim().parse().ok()).collect())
        .unwrap_or_default();
    let [t, h, w] = dims[..] else {
        return Err(invalid(
            path,
            format!("expected a (T, H, W) shape, found {header}"),
        ));
    };
    Ok((t, h, w))
}

/// Opens the archive's `depth.npy` member and hands it to `f`.
fn with_member<T>(
    path: &Path,
    f: impl FnOnce(&mut zip::read::ZipFile<'_, fs_err::File>) -> Result<T>,
) -> Result<T> {
    let file = fs_err::File::open(path).map_err(io_err("open", path))?;
    let mut zip = zip::ZipArchive::new(file).map_err(|e| invalid(path, e.to_string()))?;
    let mut member = zip
        .by_name(&format!("{DEPTH_KEY}.npy"))
        .map_err(|e| invalid(path, format!("member {DEPTH_KEY}.npy: {e}")))?;
    f(&mut member)
}

/// The (frames, height, width) shape of `<camera>_depth.npz`, from its header only.
pub fn depth_npz_shape(path: &Path) -> Result<(usize, usize, usize)> {
    with_member(path, |m| read_header(m, path))
}

/// Streams the frames of `<camera>_depth.npz` one at a time (never the whole array in
/// memory): `f(k, frame)` for each frame k (row-major, metres); stops at the first error
/// `f` returns. Returns the (frames, height, width) shape.
pub fn for_each_depth_frame<E: From<FormatError>>(
    path: &Path,
    mut f: impl FnMut(usize, &[f32]) -> std::result::Result<(), E>,
) -> std::result::Result<(usize, usize, usize), E> {
    let mut outcome: std::result::Result<(), E> = Ok(());
    let shape = with_member(path, |m| {
        let (t, h, w) = read_header(m, path)?;
        let mut bytes = vec![0u8; h * w * 4];
        let mut frame = vec![0f32; h * w];
        for k in 0..t {
            m.read_exact(&mut bytes)
                .map_err(|e| invalid(path, format!("frame {k} of {t} cannot be read: {e}")))?;
            for (v, c) in frame.iter_mut().zip(bytes.chunks_exact(4)) {
                *v = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            }
            if let Err(e) = f(k, &frame) {
                outcome = Err(e);
                return Ok((t, h, w));
            }
        }
        if m.read(&mut [0u8; 1]).map_err(io_err("read", path))? != 0 {
            return Err(invalid(path, format!("data beyond shape ({t}, {h}, {w})")));
        }
        Ok((t, h, w))
    })?;
    outcome.map(|()| shape)
}

/// Reads `<camera>_depth.npz`: (frames, height, width) and the values, row-major.
pub fn read_depth_npz(path: &Path) -> Result<((usize, usize, usize), Vec<f32>)> {
    let mut values = Vec::new();
    let shape = for_each_depth_frame::<FormatError>(path, |_, frame| {
        values.extend_from_slice(frame);
        Ok(())
    })?;
    Ok((shape, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_are_padded_to_64_bytes() {
        for shape in [&[3usize, 640, 640][..], &[1, 2, 3], &[522, 224, 224]] {
            let h = npy_header(shape);
            assert_eq!(h.len() % 64, 0);
            assert_eq!(*h.last().unwrap(), b'\n');
        }
    }

    #[test]
    fn frames_stream_in_and_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("front_depth.npz");
        let mut w = DepthWriter::create(&path, 3, 4, 2).unwrap();
        for k in 0..3 {
            let f: Vec<f32> = (0..8).map(|i| k as f32 + i as f32 * 0.125).collect();
            w.write_frame(&f).unwrap();
        }
        assert!(
            w.write_frame(&[0.0; 8]).is_err(),
            "a fourth frame is refused"
        );
        w.finish().unwrap();
        let ((t, h, wd), v) = read_depth_npz(&path).unwrap();
        assert_eq!((t, h, wd), (3, 2, 4));
        assert_eq!(v[8 + 3], 1.0 + 3.0 * 0.125);
        // Short archives are refused at finish, and nothing lands.
        let short = dir.path().join("short_depth.npz");
        let mut w = DepthWriter::create(&short, 2, 4, 2).unwrap();
        w.write_frame(&[0.0; 8]).unwrap();
        assert!(w.finish().is_err());
        assert!(!short.exists());
    }
}

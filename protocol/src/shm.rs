//! Camera frames through a shared-memory file (`"image_encoding":"shm"`,
//! negotiated in `GET_INIT_DATA`; docs/PROTOCOL.md "Images in shared
//! memory"). For a platform and a world on one host: the world writes the
//! pixels into a file under `/dev/shm` and its `GET_IMAGE` reply carries
//! only the file's path and the frame's sequence number, so no image is
//! spelled as JSON, sent through the socket or parsed.
//!
//! The file is a 32-byte header followed by the pixels, row-major, one byte
//! each (all integers little-endian):
//!
//! | bytes  | field                                   |
//! |--------|-----------------------------------------|
//! | 0..8   | magic `CFSHMIMG`                        |
//! | 8..16  | `seq`, u64: the frame's number (1, 2, …) |
//! | 16..20 | `width`, u32                            |
//! | 20..24 | `height`, u32                           |
//! | 24..32 | pixel bytes that follow, u64            |
//!
//! The world writes a frame whole (header and pixels in one `pwrite`) before
//! sending the reply that names it, and the platform reads it before its
//! next request: the lockstep alone orders the two, no lock is needed. The
//! reader checks the header against the reply (same `seq`, same size), so a
//! stale or foreign file is an error, never a wrong image.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use crate::image::Image;

/// Length of the file's header.
pub const SHM_HEADER: usize = 32;
/// The file's first 8 bytes.
pub const SHM_MAGIC: &[u8; 8] = b"CFSHMIMG";

/// What a `GET_IMAGE` reply says about a frame in shared memory:
/// `{"camera":{"encoding":"shm","height":H,"path":P,"seq":N,"width":W},"command":"GET_IMAGE"}`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ShmFrame {
    pub width: u32,
    pub height: u32,
    /// The frame's sequence number (the header's `seq`).
    pub seq: u64,
    /// The file holding the pixels.
    pub path: String,
}

/// A shared-memory file that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ShmError {
    #[error(
        "cannot open the world's shared-memory image file {path}: {source} \
         (image_encoding \"shm\" needs the platform and the world on one host; \
         use \"array\" or \"base64\" otherwise)"
    )]
    Open {
        path: String,
        source: std::io::Error,
    },
    #[error("cannot create the shared-memory image file {path}: {source}")]
    Create {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("shared-memory image file {path}: {message}")]
    Frame { path: String, message: String },
}

/// The directory for the files: `/dev/shm` (a tmpfs on Linux) when it
/// exists, else the temporary directory.
pub fn shm_dir() -> PathBuf {
    let d = Path::new("/dev/shm");
    if d.is_dir() {
        d.to_path_buf()
    } else {
        std::env::temp_dir()
    }
}

fn header(seq: u64, width: u32, height: u32, len: u64) -> [u8; SHM_HEADER] {
    let mut h = [0u8; SHM_HEADER];
    h[0..8].copy_from_slice(SHM_MAGIC);
    h[8..16].copy_from_slice(&seq.to_le_bytes());
    h[16..20].copy_from_slice(&width.to_le_bytes());
    h[20..24].copy_from_slice(&height.to_le_bytes());
    h[24..32].copy_from_slice(&len.to_le_bytes());
    h
}

/// The world's end: one file per connection, removed when dropped.
#[derive(Debug)]
pub struct ShmWriter {
    file: File,
    path: PathBuf,
    path_str: String,
    seq: u64,
    buf: Vec<u8>,
}

impl ShmWriter {
    /// Creates (truncates) `path`, mode 0600.
    pub fn create(path: PathBuf) -> Result<ShmWriter, ShmError> {
        use std::os::unix::fs::OpenOptionsExt;
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .mode(0o600)
            .open(&path)
            .map_err(|source| ShmError::Create {
                path: path.clone(),
                source,
            })?;
        let path_str = path.to_string_lossy().into_owned();
        Ok(ShmWriter {
            file,
            path,
            path_str,
            seq: 0,
            buf: Vec::new(),
        })
    }

    /// A file name for connection `index` of this process. Its length does
    /// not depend on the process id (zero-padded), so the length of the
    /// `GET_IMAGE` frames, which traces record, is the same in every run.
    pub fn default_path(index: usize) -> PathBuf {
        shm_dir().join(format!("cosim-img-{:010}-{index:04}", std::process::id()))
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes `img` as the next frame and returns what the reply says.
    pub fn write(&mut self, img: &Image) -> Result<ShmFrame, ShmError> {
        self.seq += 1;
        self.buf.clear();
        self.buf.extend_from_slice(&header(
            self.seq,
            img.width,
            img.height,
            img.data.len() as u64,
        ));
        self.buf.extend_from_slice(&img.data);
        self.file
            .write_all_at(&self.buf, 0)
            .map_err(|e| ShmError::Frame {
                path: self.path_str.clone(),
                message: format!("cannot write frame {}: {e}", self.seq),
            })?;
        Ok(ShmFrame {
            width: img.width,
            height: img.height,
            seq: self.seq,
            path: self.path_str.clone(),
        })
    }
}

impl Drop for ShmWriter {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// The platform's end: opens the file a reply names (once) and reads frames.
#[derive(Debug, Default)]
pub struct ShmReader {
    open: Option<(String, File)>,
}

impl ShmReader {
    pub fn new() -> Self {
        ShmReader::default()
    }

    /// Reads the frame `frame` announces, checking the file's header. The
    /// header and the pixels are read apart, the pixels straight into the
    /// image's buffer (no copy of a frame per image); the lockstep keeps
    /// the world from writing in between.
    pub fn read(&mut self, frame: &ShmFrame) -> Result<Image, ShmError> {
        let bad = |message: String| ShmError::Frame {
            path: frame.path.clone(),
            message,
        };
        if self.open.as_ref().map(|(p, _)| p.as_str()) != Some(frame.path.as_str()) {
            let file = File::open(&frame.path).map_err(|source| ShmError::Open {
                path: frame.path.clone(),
                source,
            })?;
            self.open = Some((frame.path.clone(), file));
        }
        let (_, file) = self.open.as_ref().expect("opened above");
        let len = u64::from(frame.width) * u64::from(frame.height);
        let len = usize::try_from(len).map_err(|_| bad(format!("{len} pixels")))?;
        let read_at = |buf: &mut [u8], offset: u64| {
            file.read_exact_at(buf, offset)
                .map_err(|e| bad(format!("cannot read frame {}: {e}", frame.seq)))
        };
        let mut got = [0u8; SHM_HEADER];
        read_at(&mut got, 0)?;
        if got != header(frame.seq, frame.width, frame.height, len as u64) {
            return Err(bad(if &got[0..8] != SHM_MAGIC {
                "not a cosim image file (bad magic)".into()
            } else {
                format!(
                    "holds frame {} ({}x{}), the reply announced frame {} ({}x{})",
                    u64::from_le_bytes(got[8..16].try_into().expect("8 bytes")),
                    u32::from_le_bytes(got[16..20].try_into().expect("4 bytes")),
                    u32::from_le_bytes(got[20..24].try_into().expect("4 bytes")),
                    frame.seq,
                    frame.width,
                    frame.height
                )
            }));
        }
        let mut data = vec![0u8; len];
        read_at(&mut data, SHM_HEADER as u64)?;
        Ok(Image {
            width: frame.width,
            height: frame.height,
            data,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(seed: u8) -> Image {
        Image {
            width: 7,
            height: 5,
            data: (0..35u8).map(|i| i.wrapping_mul(seed)).collect(),
        }
    }

    #[test]
    fn frames_round_trip_and_the_file_goes_with_the_writer() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("img");
        let mut w = ShmWriter::create(path.clone()).unwrap();
        let mut r = ShmReader::new();
        for seed in [3u8, 7, 11] {
            let f = w.write(&img(seed)).unwrap();
            assert_eq!(r.read(&f).unwrap(), img(seed));
        }
        drop(w);
        assert!(!path.exists());
    }

    #[test]
    fn a_stale_frame_or_a_missing_file_is_a_clear_error() {
        let dir = tempfile::tempdir().unwrap();
        let mut w = ShmWriter::create(dir.path().join("img")).unwrap();
        let first = w.write(&img(3)).unwrap();
        w.write(&img(5)).unwrap();
        let e = ShmReader::new().read(&first).unwrap_err().to_string();
        assert!(
            e.contains("holds frame 2") && e.contains("announced frame 1"),
            "{e}"
        );
        let missing = ShmFrame {
            path: dir.path().join("nope").to_string_lossy().into_owned(),
            ..first
        };
        let e = ShmReader::new().read(&missing).unwrap_err().to_string();
        assert!(e.contains("cannot open") && e.contains("one host"), "{e}");
    }

    #[test]
    fn default_paths_have_one_length() {
        assert_eq!(
            ShmWriter::default_path(0).as_os_str().len(),
            ShmWriter::default_path(999).as_os_str().len()
        );
    }
}

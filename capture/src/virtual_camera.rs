//! Frames for libcamera's `virtual` camera: JPEG images named `0.jpg`, `1.jpg`, ... and the
//! `virtual.yaml` that makes libcamera offer a camera playing them. With the simulator's frames
//! this runs the real libcamera path (camera manager, buffers, requests) on a machine without a
//! camera. The virtual camera decodes each JPEG to NV12 once; its Y plane is the luminance the
//! capture stage reads.

use deckwatch_common::GrayView;
use jpeg_encoder::{ColorType, Encoder};
use std::path::{Path, PathBuf};

/// Why a virtual camera's frames cannot be written.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum VirtualCameraError {
    /// A file or folder that cannot be written, and why.
    #[error("{}: {problem}", path.display())]
    File { path: PathBuf, problem: String },
    /// An id, a frame size or an empty run that no virtual camera can be made of.
    #[error("virtual camera: {0}")]
    Invalid(String),
}

fn file_error(path: &Path, problem: impl std::fmt::Display) -> VirtualCameraError {
    VirtualCameraError::File {
        path: path.to_path_buf(),
        problem: problem.to_string(),
    }
}

/// JPEG quality of the frames: high enough that compression moves a marker's centroid far less
/// than the renderer's own noise does.
pub const JPEG_QUALITY: u8 = 100;

/// Writes a gray image as a JPEG (YCbCr with neutral chroma: libcamera's decoder gives back the
/// gray levels, up to compression, as the Y plane).
pub fn write_gray_jpeg(path: &Path, image: GrayView<'_>) -> Result<(), VirtualCameraError> {
    let (w, h) = (image.width(), image.height());
    let (w16, h16) = (
        u16::try_from(w).map_err(|_| file_error(path, format!("width {w} is too large for JPEG")))?,
        u16::try_from(h).map_err(|_| file_error(path, format!("height {h} is too large for JPEG")))?,
    );
    let mut ycbcr = Vec::with_capacity(3 * w * h);
    for y in 0..h {
        for &v in image.row(y) {
            ycbcr.extend_from_slice(&[v, 128, 128]);
        }
    }
    let encoder = Encoder::new_file(path, JPEG_QUALITY).map_err(|e| file_error(path, e))?;
    encoder
        .encode(&ycbcr, w16, h16, ColorType::Ycbcr)
        .map_err(|e| file_error(path, e))
}

/// The `virtual.yaml` entry of one camera `id` playing the JPEGs in `frames_dir` (which must
/// end in `/` for libcamera to take it as a folder) at `width` x `height`.
pub fn virtual_camera_yaml(id: &str, width: u32, height: u32, frame_rate: u32, frames_dir: &Path) -> String {
    let mut dir = frames_dir.display().to_string();
    if !dir.ends_with('/') {
        dir.push('/');
    }
    format!(
        "%YAML 1.1\n---\n\
         # libcamera's virtual camera playing deckwatch simulator frames. Install as\n\
         # /usr/share/libcamera/pipeline/virtual/virtual.yaml (or /etc/libcamera/pipeline/virtual/).\n\
         \"{id}\":\n  supported_formats:\n  - width: {width}\n    height: {height}\n    frame_rates:\n    - {frame_rate}\n  \
         frames:\n    path: \"{dir}\"\n  location: \"CameraLocationBack\"\n  model: \"deckwatch simulator\"\n"
    )
}

/// Writes a virtual camera's frames one by one into `dir/frames/`, then `dir/virtual.yaml`.
/// (Not beside the frames: libcamera takes every file of the frames folder for an image.)
pub struct VirtualCameraWriter {
    dir: PathBuf,
    frames: PathBuf,
    id: String,
    written: u64,
    size: Option<(u32, u32)>,
}

impl VirtualCameraWriter {
    /// Creates `dir` (absolute paths only: libcamera resolves the yaml's path on its own).
    pub fn create(dir: &Path, id: &str) -> Result<Self, VirtualCameraError> {
        let dir = std::path::absolute(dir).map_err(|e| file_error(dir, e))?;
        if id.is_empty() || id.contains(['"', '\n']) {
            return Err(VirtualCameraError::Invalid(format!(
                "id `{id}`: give a plain name"
            )));
        }
        let frames = dir.join("frames");
        std::fs::create_dir_all(&frames).map_err(|e| file_error(&frames, format!("cannot create: {e}")))?;
        Ok(Self {
            dir,
            frames,
            id: id.into(),
            written: 0,
            size: None,
        })
    }

    /// Appends the next frame (all frames must have one size).
    pub fn write_frame(&mut self, image: GrayView<'_>) -> Result<(), VirtualCameraError> {
        let size = (image.width() as u32, image.height() as u32);
        if *self.size.get_or_insert(size) != size {
            return Err(VirtualCameraError::Invalid(format!(
                "frames must all be {:?}, got {size:?}",
                self.size
            )));
        }
        write_gray_jpeg(&self.frames.join(format!("{}.jpg", self.written)), image)?;
        self.written += 1;
        Ok(())
    }

    /// Writes `virtual.yaml` beside the frames and returns its path.
    pub fn finish(self, frame_rate: f64) -> Result<PathBuf, VirtualCameraError> {
        let (w, h) = self
            .size
            .ok_or_else(|| VirtualCameraError::Invalid("no frames written".into()))?;
        let path = self.dir.join("virtual.yaml");
        let rate = frame_rate.round().clamp(1.0, 1000.0) as u32;
        std::fs::write(&path, virtual_camera_yaml(&self.id, w, h, rate, &self.frames))
            .map_err(|e| file_error(&path, e))?;
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::GrayImage;

    #[test]
    fn frames_and_yaml() {
        let dir = std::env::temp_dir().join(format!("dw-virtual-{}", std::process::id()));
        let mut w = VirtualCameraWriter::create(&dir, "deckwatch-test").unwrap();
        let mut img = GrayImage::new(64, 48);
        img.data
            .iter_mut()
            .enumerate()
            .for_each(|(i, v)| *v = (i % 251) as u8);
        w.write_frame(img.view()).unwrap();
        w.write_frame(img.view()).unwrap();
        assert!(w.write_frame(GrayImage::new(32, 48).view()).is_err());
        let yaml = w.finish(10.0).unwrap();
        let text = std::fs::read_to_string(&yaml).unwrap();
        assert!(
            text.contains("\"deckwatch-test\":") && text.contains("width: 64"),
            "{text}"
        );
        assert!(
            text.contains(&format!("path: \"{}/frames/\"", dir.display())),
            "{text}"
        );
        let jpeg = std::fs::read(dir.join("frames/1.jpg")).unwrap();
        assert_eq!(&jpeg[..2], &[0xFF, 0xD8], "a JPEG");
        std::fs::remove_dir_all(dir).unwrap();
    }
}

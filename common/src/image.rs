//! 8-bit grayscale images as (width, height, stride) views over borrowed memory, so that the same
//! code reads a frame in iceoryx2 shared memory, a decoded PNG or a test buffer.

use std::fmt;

/// Why a buffer cannot be viewed as an image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ImageError {
    ZeroSize { width: usize, height: usize },
    StrideTooSmall { width: usize, stride: usize },
    BufferTooSmall { needed: usize, len: usize },
}

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::ZeroSize { width, height } => write!(f, "image has zero size ({width}x{height})"),
            Self::StrideTooSmall { width, stride } => {
                write!(f, "stride {stride} is smaller than the width {width}")
            }
            Self::BufferTooSmall { needed, len } => {
                write!(
                    f,
                    "buffer of {len} bytes is too small for the image ({needed} bytes)"
                )
            }
        }
    }
}

impl std::error::Error for ImageError {}

fn check(len: usize, width: usize, height: usize, stride: usize) -> Result<(), ImageError> {
    if width == 0 || height == 0 {
        return Err(ImageError::ZeroSize { width, height });
    }
    if stride < width {
        return Err(ImageError::StrideTooSmall { width, stride });
    }
    // The last row needs only `width` bytes, not a whole stride.
    let needed = stride
        .checked_mul(height - 1)
        .and_then(|n| n.checked_add(width))
        .ok_or(ImageError::BufferTooSmall {
            needed: usize::MAX,
            len,
        })?;
    if len < needed {
        return Err(ImageError::BufferTooSmall { needed, len });
    }
    Ok(())
}

/// The grey of an RGB pixel: BT.601's weights in 1/256ths (77 + 150 + 29 = 256), rounded; what
/// a camera's RGB frames and a colour photograph become.
pub fn luma_bt601(r: u8, g: u8, b: u8) -> u8 {
    ((77 * u32::from(r) + 150 * u32::from(g) + 29 * u32::from(b) + 128) >> 8) as u8
}

/// A read-only 8-bit grayscale image.
#[derive(Debug, Clone, Copy)]
pub struct GrayView<'a> {
    width: usize,
    height: usize,
    stride: usize,
    data: &'a [u8],
}

impl<'a> GrayView<'a> {
    pub fn new(data: &'a [u8], width: usize, height: usize, stride: usize) -> Result<Self, ImageError> {
        check(data.len(), width, height, stride)?;
        Ok(Self {
            width,
            height,
            stride,
            data,
        })
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    pub fn stride(&self) -> usize {
        self.stride
    }
    /// The underlying bytes (rows `stride` apart).
    pub fn data(&self) -> &'a [u8] {
        self.data
    }

    /// Row `y` (exactly `width` bytes).
    pub fn row(&self, y: usize) -> &'a [u8] {
        let start = y * self.stride;
        &self.data[start..start + self.width]
    }

    pub fn get(&self, x: usize, y: usize) -> u8 {
        self.data[y * self.stride + x]
    }
}

/// A writable 8-bit grayscale image.
#[derive(Debug)]
pub struct GrayViewMut<'a> {
    width: usize,
    height: usize,
    stride: usize,
    data: &'a mut [u8],
}

impl<'a> GrayViewMut<'a> {
    pub fn new(data: &'a mut [u8], width: usize, height: usize, stride: usize) -> Result<Self, ImageError> {
        check(data.len(), width, height, stride)?;
        Ok(Self {
            width,
            height,
            stride,
            data,
        })
    }

    pub fn width(&self) -> usize {
        self.width
    }
    pub fn height(&self) -> usize {
        self.height
    }
    pub fn stride(&self) -> usize {
        self.stride
    }

    pub fn row_mut(&mut self, y: usize) -> &mut [u8] {
        let start = y * self.stride;
        &mut self.data[start..start + self.width]
    }

    pub fn as_view(&self) -> GrayView<'_> {
        GrayView {
            width: self.width,
            height: self.height,
            stride: self.stride,
            data: self.data,
        }
    }
}

/// An owned, tightly packed (stride = width) 8-bit grayscale image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct GrayImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

impl GrayImage {
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            data: vec![0; width * height],
        }
    }

    pub fn view(&self) -> GrayView<'_> {
        GrayView {
            width: self.width,
            height: self.height,
            stride: self.width,
            data: &self.data,
        }
    }

    pub fn view_mut(&mut self) -> GrayViewMut<'_> {
        GrayViewMut {
            width: self.width,
            height: self.height,
            stride: self.width,
            data: &mut self.data,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_check_their_geometry() {
        let buf = vec![7u8; 10 * 3];
        assert!(GrayView::new(&buf, 8, 3, 10).is_ok());
        // Last row needs only `width` bytes.
        assert!(GrayView::new(&buf[..28], 8, 3, 10).is_ok());
        assert_eq!(
            GrayView::new(&buf[..27], 8, 3, 10).unwrap_err(),
            ImageError::BufferTooSmall { needed: 28, len: 27 }
        );
        assert!(matches!(
            GrayView::new(&buf, 0, 3, 10),
            Err(ImageError::ZeroSize { .. })
        ));
        assert!(matches!(
            GrayView::new(&buf, 8, 0, 10),
            Err(ImageError::ZeroSize { .. })
        ));
        assert!(matches!(
            GrayView::new(&buf, 11, 2, 10),
            Err(ImageError::StrideTooSmall { .. })
        ));
        assert!(GrayView::new(&buf, usize::MAX, 2, usize::MAX).is_err());
        let v = GrayView::new(&buf, 8, 3, 10).unwrap();
        assert_eq!(v.row(2).len(), 8);
    }
}

//! A camera's image pipeline after the sensor, applied to a rendered frame: other optics and
//! other image processing than the renderer's own, for judging the detector on frames it was
//! not tuned on. In a camera's order:
//!
//! 1. the point-spread function of a lens that is not the renderer's Gaussian: defocus (a
//!    disc), motion (a line) or a measured kernel;
//! 2. a Bayer sensor: the grey scene through red, green and blue filters of different
//!    sensitivity (an RGGB mosaic), quantised at the raw bit depth, white-balanced and
//!    demosaiced (bilinear), then taken to luma (BT.601 weights);
//! 3. the ISP's denoising (a Gaussian) and sharpening (an unsharp mask);
//! 4. a tone curve (a gamma: the detector's levels are no longer linear in the light);
//! 5. 8 bits, and a stream's JPEG compression (encoded and decoded).
//!
//! The renderer's noise is in the frame before these (a lens's blur comes before the noise in
//! a camera: a point-spread function here smooths the noise too, so its frames are slightly
//! less noisy than a real lens's would be). Deterministic: no randomness of its own.

use deckwatch_common::image::GrayViewMut;
use deckwatch_common::jpeg;
use deckwatch_common::InvalidField;

/// Sensitivities of the red, green and blue pixels of an RGGB sensor to a grey scene in
/// daylight before white balance (a small CMOS sensor's, about those of the IMX219).
const BAYER_SENSITIVITY: [f64; 3] = [0.55, 1.0, 0.45];
/// Luma from RGB (BT.601).
const LUMA: [f64; 3] = [0.299, 0.587, 0.114];
/// The unsharp mask's blur (Gaussian sigma, px).
const SHARPEN_SIGMA_PX: f64 = 1.0;
/// The largest point-spread function kernel side (px).
const MAX_KERNEL_SIDE: usize = 63;

/// The lens's point-spread function beyond the renderer's Gaussian (`RenderOptions::optical_blur_px`).
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Psf {
    #[default]
    None,
    /// Out of focus: a uniform disc of this radius (px).
    Defocus { radius_px: f64 },
    /// Motion during the exposure: a line this long (px) at this angle (deg from +u toward +v).
    Motion { length_px: f64, angle_deg: f64 },
    /// A measured kernel: `side` x `side` weights, row by row (normalised when applied).
    Kernel { side: usize, weights: Vec<f64> },
}

impl Psf {
    /// A measured kernel from text: rows of numbers separated by spaces, commas or tabs, as
    /// many rows as columns, an odd side up to 63; `#` starts a comment. The error names the
    /// line.
    pub fn kernel_from_text(text: &str) -> Result<Self, InvalidField> {
        let mut rows: Vec<Vec<f64>> = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let row = line
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .map(|s| {
                    s.parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite() && *v >= 0.0)
                        .ok_or_else(|| {
                            InvalidField::new(
                                "psf kernel",
                                format!("line {}: `{s}` is not a weight >= 0", n + 1),
                            )
                        })
                })
                .collect::<Result<Vec<f64>, _>>()?;
            rows.push(row);
        }
        let side = rows.len();
        if side == 0 || side.is_multiple_of(2) || side > MAX_KERNEL_SIDE {
            return Err(InvalidField::new(
                "psf kernel",
                format!("{side} rows: an odd number up to {MAX_KERNEL_SIDE} needed"),
            ));
        }
        if let Some(k) = rows.iter().position(|r| r.len() != side) {
            return Err(InvalidField::new(
                "psf kernel",
                format!(
                    "row {} has {} weights, the kernel is {side} x {side}",
                    k + 1,
                    rows[k].len()
                ),
            ));
        }
        let weights: Vec<f64> = rows.concat();
        if !(weights.iter().sum::<f64>() > 0.0) {
            return Err(InvalidField::new("psf kernel", "the weights sum to 0"));
        }
        Ok(Self::Kernel { side, weights })
    }

    /// The kernel (side, weights summing to 1); None for no blur.
    fn kernel(&self) -> Option<(usize, Vec<f64>)> {
        let (side, mut w) = match self {
            Self::None => return None,
            Self::Defocus { radius_px } => {
                let r = *radius_px;
                let half = r.ceil() as usize;
                let side = 2 * half + 1;
                // Each cell's share of the disc, by 8 x 8 samples.
                const S: usize = 8;
                let mut w = vec![0.0; side * side];
                for y in 0..side {
                    for x in 0..side {
                        let mut inside = 0;
                        for sy in 0..S {
                            for sx in 0..S {
                                let dx = x as f64 - half as f64 + (sx as f64 + 0.5) / S as f64 - 0.5;
                                let dy = y as f64 - half as f64 + (sy as f64 + 0.5) / S as f64 - 0.5;
                                inside += usize::from(dx * dx + dy * dy <= r * r);
                            }
                        }
                        w[y * side + x] = inside as f64;
                    }
                }
                (side, w)
            }
            Self::Motion { length_px, angle_deg } => {
                let (l, a) = (*length_px, angle_deg.to_radians());
                let half = (0.5 * l).ceil() as usize + 1;
                let side = 2 * half + 1;
                let mut w = vec![0.0; side * side];
                // Points along the segment, each spread bilinearly over its four cells.
                let steps = (8.0 * l).ceil().max(1.0) as usize;
                for k in 0..=steps {
                    let s = (k as f64 / steps as f64 - 0.5) * l;
                    let (x, y) = (half as f64 + s * a.cos(), half as f64 + s * a.sin());
                    let (x0, y0) = (x.floor(), y.floor());
                    let (fx, fy) = (x - x0, y - y0);
                    for (dx, dy, share) in [
                        (0, 0, (1.0 - fx) * (1.0 - fy)),
                        (1, 0, fx * (1.0 - fy)),
                        (0, 1, (1.0 - fx) * fy),
                        (1, 1, fx * fy),
                    ] {
                        let (cx, cy) = (x0 as usize + dx, y0 as usize + dy);
                        if cx < side && cy < side {
                            w[cy * side + cx] += share;
                        }
                    }
                }
                (side, w)
            }
            Self::Kernel { side, weights } => (*side, weights.clone()),
        };
        let sum: f64 = w.iter().sum();
        w.iter_mut().for_each(|v| *v /= sum);
        Some((side, w))
    }

    fn validate(&self) -> Result<(), InvalidField> {
        let ok = match self {
            Self::None => true,
            Self::Defocus { radius_px } => *radius_px > 0.0 && *radius_px <= 31.0,
            Self::Motion { length_px, angle_deg } => {
                *length_px > 0.0 && *length_px <= 60.0 && angle_deg.is_finite()
            }
            Self::Kernel { side, weights } => {
                !side.is_multiple_of(2) && *side <= MAX_KERNEL_SIDE && weights.len() == side * side
            }
        };
        if ok {
            Ok(())
        } else {
            Err(InvalidField::new(
                "psf",
                format!("{self:?}: a defocus radius within (0, 31] px, a motion length within (0, 60] px, or an odd kernel up to {MAX_KERNEL_SIDE}"),
            ))
        }
    }
}

/// The image pipeline (the default changes nothing).
#[derive(Debug, Clone, PartialEq)]
pub struct ImagePipeline {
    pub psf: Psf,
    /// Through an RGGB Bayer mosaic and its demosaicing to luma.
    pub bayer: bool,
    /// The raw bit depth of the Bayer path (8 or 10; the dim red and blue pixels lose levels
    /// at 8).
    pub raw_bits: u32,
    /// The ISP's denoising: a Gaussian of this sigma (px; 0 = none).
    pub denoise_px: f64,
    /// The ISP's sharpening: an unsharp mask of this amount (0 = none; 1 doubles the detail).
    pub sharpen: f64,
    /// Tone curve: `255 (x / 255)^(1 / gamma)` (1 = linear).
    pub gamma: f64,
    /// JPEG quality of the streamed frame (0 = not compressed; 1-100).
    pub jpeg_quality: u8,
}

impl Default for ImagePipeline {
    fn default() -> Self {
        Self {
            psf: Psf::None,
            bayer: false,
            raw_bits: 8,
            denoise_px: 0.0,
            sharpen: 0.0,
            gamma: 1.0,
            jpeg_quality: 0,
        }
    }
}

/// Why the pipeline could not process a frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PipelineError {
    #[error("JPEG compression: {0}")]
    Jpeg(String),
}

impl ImagePipeline {
    /// Whether it changes nothing (the renderer skips it).
    pub fn is_identity(&self) -> bool {
        *self == Self::default()
    }

    /// Checks every field; the error names it.
    pub fn validate(&self) -> Result<(), InvalidField> {
        self.psf.validate()?;
        if ![8, 10].contains(&self.raw_bits) {
            return Err(InvalidField::new(
                "raw_bits",
                format!("8 or 10, got {}", self.raw_bits),
            ));
        }
        for (name, v, hi) in [
            ("denoise_px", self.denoise_px, 10.0),
            ("sharpen", self.sharpen, 5.0),
        ] {
            if !(v >= 0.0 && v <= hi) {
                return Err(InvalidField::new(
                    name,
                    format!("must be within [0, {hi}], got {v}"),
                ));
            }
        }
        if !(self.gamma >= 0.2 && self.gamma <= 5.0) {
            return Err(InvalidField::new(
                "gamma",
                format!("must be within [0.2, 5], got {}", self.gamma),
            ));
        }
        if self.jpeg_quality > 100 {
            return Err(InvalidField::new(
                "jpeg_quality",
                format!("0 (none) or 1-100, got {}", self.jpeg_quality),
            ));
        }
        Ok(())
    }

    /// Runs the frame through the pipeline, in place.
    pub fn apply(&self, out: &mut GrayViewMut<'_>) -> Result<(), PipelineError> {
        let (w, h) = (out.width(), out.height());
        let mut img: Vec<f64> = Vec::with_capacity(w * h);
        for y in 0..h {
            img.extend(out.row_mut(y)[..w].iter().map(|&p| f64::from(p)));
        }
        if let Some((side, kernel)) = self.psf.kernel() {
            img = convolve(&img, w, h, side, &kernel);
        }
        if self.bayer {
            img = bayer_to_luma(&img, w, h, self.raw_bits);
        }
        if self.denoise_px > 0.0 {
            img = gaussian(&img, w, h, self.denoise_px);
        }
        if self.sharpen > 0.0 {
            let smooth = gaussian(&img, w, h, SHARPEN_SIGMA_PX);
            for (v, s) in img.iter_mut().zip(&smooth) {
                *v += self.sharpen * (*v - s);
            }
        }
        if self.gamma != 1.0 {
            for v in &mut img {
                *v = 255.0 * (v.clamp(0.0, 255.0) / 255.0).powf(1.0 / self.gamma);
            }
        }
        for y in 0..h {
            for (p, v) in out.row_mut(y)[..w].iter_mut().zip(&img[y * w..(y + 1) * w]) {
                *p = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        if self.jpeg_quality > 0 {
            jpeg_round_trip(out, self.jpeg_quality)?;
        }
        Ok(())
    }
}

/// `img` convolved with a `side` x `side` kernel, the border extended.
fn convolve(img: &[f64], w: usize, h: usize, side: usize, kernel: &[f64]) -> Vec<f64> {
    let half = (side / 2) as isize;
    let taps: Vec<(isize, isize, f64)> = (0..side * side)
        .filter(|&k| kernel[k] != 0.0)
        .map(|k| ((k % side) as isize - half, (k / side) as isize - half, kernel[k]))
        .collect();
    let at = |x: isize, y: isize| {
        img[y.clamp(0, h as isize - 1) as usize * w + x.clamp(0, w as isize - 1) as usize]
    };
    let mut out = vec![0.0; w * h];
    for y in 0..h as isize {
        for x in 0..w as isize {
            out[y as usize * w + x as usize] = taps.iter().map(|&(dx, dy, k)| k * at(x + dx, y + dy)).sum();
        }
    }
    out
}

/// A separable Gaussian blur of `sigma` px, the border extended.
fn gaussian(img: &[f64], w: usize, h: usize, sigma: f64) -> Vec<f64> {
    let half = (3.0 * sigma).ceil() as isize;
    let mut k: Vec<f64> = (-half..=half)
        .map(|i| (-0.5 * (i as f64 / sigma).powi(2)).exp())
        .collect();
    let sum: f64 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w as isize {
            tmp[y * w + x as usize] = (-half..=half)
                .map(|i| k[(i + half) as usize] * img[y * w + (x + i).clamp(0, w as isize - 1) as usize])
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h as isize {
        for x in 0..w {
            out[y as usize * w + x] = (-half..=half)
                .map(|i| k[(i + half) as usize] * tmp[(y + i).clamp(0, h as isize - 1) as usize * w + x])
                .sum();
        }
    }
    out
}

/// The colour of an RGGB mosaic's pixel: 0 red, 1 green, 2 blue.
fn bayer_channel(x: usize, y: usize) -> usize {
    match (x % 2, y % 2) {
        (0, 0) => 0,
        (1, 1) => 2,
        _ => 1,
    }
}

/// A grey scene through an RGGB mosaic: each pixel its filter's share of the light, quantised
/// at `raw_bits`, white-balanced, each colour interpolated bilinearly from its neighbours of
/// that colour, and the three taken to luma.
fn bayer_to_luma(img: &[f64], w: usize, h: usize, raw_bits: u32) -> Vec<f64> {
    let levels = f64::from((1u32 << raw_bits) - 1);
    // Raw, quantised, then white-balanced back to the scene's scale.
    let balanced: Vec<f64> = (0..w * h)
        .map(|i| {
            let s = BAYER_SENSITIVITY[bayer_channel(i % w, i / w)];
            let raw = (img[i] / 255.0 * s * levels).round().clamp(0.0, levels);
            raw / levels * 255.0 / s
        })
        .collect();
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut rgb = [0.0; 3];
            let mut count = [0u32; 3];
            // The 3 x 3 neighbourhood holds every colour; a pixel's own colour is its own.
            let own = bayer_channel(x, y);
            rgb[own] = balanced[y * w + x];
            count[own] = 1;
            for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    let (nx, ny) = (x as isize + dx, y as isize + dy);
                    if (dx == 0 && dy == 0) || nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                        continue;
                    }
                    let c = bayer_channel(nx as usize, ny as usize);
                    if c == own {
                        continue;
                    }
                    rgb[c] += balanced[ny as usize * w + nx as usize];
                    count[c] += 1;
                }
            }
            out[y * w + x] = (0..3)
                .map(|c| {
                    LUMA[c]
                        * if count[c] > 0 {
                            rgb[c] / f64::from(count[c])
                        } else {
                            rgb[own]
                        }
                })
                .sum();
        }
    }
    out
}

/// The frame encoded as a greyscale JPEG of `quality` and decoded again.
fn jpeg_round_trip(out: &mut GrayViewMut<'_>, quality: u8) -> Result<(), PipelineError> {
    let (w, h) = (out.width(), out.height());
    let mut pixels = Vec::with_capacity(w * h);
    for y in 0..h {
        pixels.extend_from_slice(&out.row_mut(y)[..w]);
    }
    let jpeg_error = |e: jpeg::JpegError| PipelineError::Jpeg(e.0);
    let (dw, dh, decoded) =
        jpeg::decode_gray(&jpeg::encode_gray(&pixels, w, h, quality).map_err(jpeg_error)?)
            .map_err(jpeg_error)?;
    if (dw as usize, dh as usize) != (w, h) {
        return Err(PipelineError::Jpeg(format!("decoded {dw}x{dh} for {w}x{h}")));
    }
    for y in 0..h {
        out.row_mut(y)[..w].copy_from_slice(&decoded[y * w..(y + 1) * w]);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use deckwatch_common::GrayImage;

    fn frame() -> GrayImage {
        let mut img = GrayImage::new(64, 48);
        let mut v = img.view_mut();
        for y in 0..48 {
            for (x, p) in v.row_mut(y)[..64].iter_mut().enumerate() {
                let d = ((x as f64 - 30.0).powi(2) + (y as f64 - 20.0).powi(2)).sqrt();
                *p = if d < 8.0 {
                    230
                } else {
                    70 + ((x * 7 + y * 13) % 11) as u8
                };
            }
        }
        img
    }

    fn run(p: &ImagePipeline) -> Vec<u8> {
        let mut img = frame();
        p.apply(&mut img.view_mut()).unwrap();
        img.view().data().to_vec()
    }

    #[test]
    fn the_default_changes_nothing_and_each_option_something_the_same_way_each_time() {
        assert!(ImagePipeline::default().is_identity());
        assert_eq!(run(&ImagePipeline::default()), frame().view().data());
        let options = [
            ImagePipeline {
                psf: Psf::Defocus { radius_px: 2.0 },
                ..Default::default()
            },
            ImagePipeline {
                psf: Psf::Motion {
                    length_px: 5.0,
                    angle_deg: 30.0,
                },
                ..Default::default()
            },
            ImagePipeline {
                bayer: true,
                ..Default::default()
            },
            ImagePipeline {
                bayer: true,
                raw_bits: 10,
                ..Default::default()
            },
            ImagePipeline {
                denoise_px: 1.0,
                ..Default::default()
            },
            ImagePipeline {
                sharpen: 1.0,
                ..Default::default()
            },
            ImagePipeline {
                gamma: 2.2,
                ..Default::default()
            },
            ImagePipeline {
                jpeg_quality: 60,
                ..Default::default()
            },
        ];
        for p in &options {
            p.validate().unwrap();
            let once = run(p);
            assert_ne!(once, frame().view().data(), "{p:?} changed nothing");
            assert_eq!(once, run(p), "{p:?} is not deterministic");
        }
    }

    /// Known answers: a kernel sums to 1 and is centred; a flat grey stays grey through the
    /// Bayer path at 10 bits (white balance undoes the filters) and through the blurs; a
    /// gamma of 2 takes 64 to 128.
    #[test]
    fn known_answers() {
        for psf in [
            Psf::Defocus { radius_px: 2.5 },
            Psf::Motion {
                length_px: 6.0,
                angle_deg: 45.0,
            },
        ] {
            let (side, k) = psf.kernel().unwrap();
            assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let half = (side / 2) as f64;
            let (mx, my) = k.iter().enumerate().fold((0.0, 0.0), |(a, b), (i, v)| {
                (
                    a + v * ((i % side) as f64 - half),
                    b + v * ((i / side) as f64 - half),
                )
            });
            assert!(
                mx.abs() < 1e-9 && my.abs() < 1e-9,
                "{psf:?} off centre: {mx} {my}"
            );
        }
        let flat = vec![100.0; 16 * 16];
        let luma = bayer_to_luma(&flat, 16, 16, 10);
        assert!(luma.iter().all(|v| (v - 100.0).abs() < 0.3), "{luma:?}");
        assert!(gaussian(&flat, 16, 16, 1.5)
            .iter()
            .all(|v| (v - 100.0).abs() < 1e-9));
        let mut img = GrayImage::new(4, 4);
        img.view_mut().row_mut(0)[0] = 64;
        ImagePipeline {
            gamma: 2.0,
            ..Default::default()
        }
        .apply(&mut img.view_mut())
        .unwrap();
        assert_eq!(img.view().row(0)[0], 128);
    }

    #[test]
    fn a_kernel_file_is_read_and_its_errors_name_the_line() {
        let k = Psf::kernel_from_text("# a 3 x 3 box\n1 1 1\n1,1,1\n1\t1 1\n").unwrap();
        assert_eq!(
            k,
            Psf::Kernel {
                side: 3,
                weights: vec![1.0; 9]
            }
        );
        let e = Psf::kernel_from_text("1 1 1\n1 x 1\n1 1 1").unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
        assert!(Psf::kernel_from_text("1 1\n1 1").is_err(), "an even side");
        assert!(Psf::kernel_from_text("1 1 1\n1 1\n1 1 1")
            .unwrap_err()
            .to_string()
            .contains("row 2"));
        assert!(ImagePipeline {
            raw_bits: 12,
            ..Default::default()
        }
        .validate()
        .is_err());
    }
}

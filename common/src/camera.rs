//! Pinhole camera with optional Brown-Conrady distortion (OpenCV's model and pixel convention:
//! u right, v down, pixel centres at integers, (0, 0) = centre of the top-left pixel).

#[cfg(feature = "shm")]
use iceoryx2::prelude::ZeroCopySend;
use nalgebra::Vector3;

/// Brown-Conrady coefficients in OpenCV's order `[k1, k2, p1, p2, k3]`, acting on normalised
/// image coordinates (x/z, y/z).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.Distortion.v1"))]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Distortion {
    pub const NONE: Self = Self {
        k1: 0.0,
        k2: 0.0,
        p1: 0.0,
        p2: 0.0,
        k3: 0.0,
    };

    pub fn from_array(a: [f64; 5]) -> Self {
        Self {
            k1: a[0],
            k2: a[1],
            p1: a[2],
            p2: a[3],
            k3: a[4],
        }
    }

    pub fn to_array(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    pub fn is_none(&self) -> bool {
        self.to_array().iter().all(|&k| k == 0.0)
    }

    /// Distorted normalised coordinates of ideal normalised coordinates.
    pub fn apply(&self, [x, y]: [f64; 2]) -> [f64; 2] {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        [
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        ]
    }

    /// Ideal normalised coordinates whose distorted image is `d`, by Newton's method on the
    /// exact model (converges to machine precision; OpenCV's fixed-point iteration does not).
    /// None where the model does not invert (far outside the calibrated field).
    pub fn remove(&self, d: [f64; 2]) -> Option<[f64; 2]> {
        if self.is_none() {
            return Some(d);
        }
        let [mut x, mut y] = d;
        for _ in 0..50 {
            let [fx, fy] = self.apply([x, y]);
            let (ex, ey) = (fx - d[0], fy - d[1]);
            // Jacobian of apply().
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dradial = self.k1 + r2 * (2.0 * self.k2 + 3.0 * r2 * self.k3); // d radial / d r2
            let j00 = radial + 2.0 * x * x * dradial + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
            let j01 = 2.0 * x * y * dradial + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
            let j10 = 2.0 * x * y * dradial + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
            let j11 = radial + 2.0 * y * y * dradial + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
            let det = j00 * j11 - j01 * j10;
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            let dx = (j11 * ex - j01 * ey) / det;
            let dy = (j00 * ey - j10 * ex) / det;
            x -= dx;
            y -= dy;
            if dx.abs().max(dy.abs()) <= 1e-16 * (1.0 + x.abs().max(y.abs())) {
                break;
            }
        }
        let [fx, fy] = self.apply([x, y]);
        let err = (fx - d[0]).abs().max((fy - d[1]).abs());
        (err <= 1e-12 * (1.0 + d[0].abs().max(d[1].abs())) && x.is_finite() && y.is_finite())
            .then_some([x, y])
    }
}

/// Intrinsics of a pinhole camera; distortion optional. `#[repr(C)]`: every pipeline message
/// carries the camera its pixels belong to.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::AnyBitPattern)]
#[cfg_attr(feature = "shm", derive(ZeroCopySend), type_name("deckwatch.CameraModel.v2"))]
pub struct CameraModel {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub distortion: Distortion,
    /// Rolling shutter: the time from the first row's exposure to the last row's (s); 0 = a
    /// global shutter. A frame's instant is its middle row's mid-exposure
    /// ([`CameraModel::row_time_s`]).
    pub readout_s: f64,
}

/// The camera presets deckwatch knows by name.
pub const CAMERA_PRESETS: [&str; 3] = ["paper", "rpi-v2", "rpi-v3-wide"];

/// The largest image side accepted (px): beyond any sensor, and small enough that a frame's
/// size in bytes cannot overflow.
pub const MAX_SIDE_PX: u32 = 32_768;
/// The most pixels an image read from a file may have: four times the largest sensor a drone
/// here carries (the Pi HQ camera's 4056 x 3040, 12.3 MP), and 64 MB of grayscale at most. A
/// file's header is checked against it before any pixel is decoded or allocated.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 26;

/// Whether an image of `width` x `height` may be read: each side within [`MAX_SIDE_PX`], the
/// whole within [`MAX_IMAGE_PIXELS`]; the error says which bound it passes.
pub fn check_image_size(width: u32, height: u32) -> Result<(), String> {
    let pixels = u64::from(width) * u64::from(height);
    if width == 0 || height == 0 || width > MAX_SIDE_PX || height > MAX_SIDE_PX {
        Err(format!(
            "an image of {width}x{height}: each side must be 1..={MAX_SIDE_PX} px"
        ))
    } else if pixels > MAX_IMAGE_PIXELS {
        Err(format!(
            "an image of {width}x{height} ({pixels} pixels): deckwatch reads at most {MAX_IMAGE_PIXELS}"
        ))
    } else {
        Ok(())
    }
}

/// The longest focal length accepted, in image sides (a 0.3 deg field of view).
pub const MAX_FOCAL_SIDES: f64 = 200.0;
/// The longest rolling-shutter readout accepted (s): a frame's rows are read within a frame
/// time, and no sensor mode is slower than 1 fps.
pub const MAX_READOUT_S: f64 = 1.0;
/// The largest distortion coefficient accepted (OpenCV's fits stay far below).
pub const MAX_DISTORTION: f64 = 1e3;

impl CameraModel {
    /// A distortion-free camera with the principal point at the image centre.
    pub fn centred(width: u32, height: u32, fx: f64, fy: f64) -> Self {
        Self {
            width,
            height,
            fx,
            fy,
            // Pixel centres at integers: the centre of a W-pixel row is (W - 1) / 2.
            cx: (width as f64 - 1.0) / 2.0,
            cy: (height as f64 - 1.0) / 2.0,
            distortion: Distortion::NONE,
            readout_s: 0.0,
        }
    }

    /// The paper's camera: 3280x2464 with focal angles 45.4 x 31.1 deg (non-square pixels:
    /// fx = 1640 / tan(22.7 deg) = 3920.55 (sometimes rounded to 3919.5; CONVENTIONS.md §3), fy = 1232 / tan(15.55 deg) = 4427.4).
    pub fn paper() -> Self {
        Self::centred(
            3280,
            2464,
            1640.0 / 22.7f64.to_radians().tan(),
            1232.0 / 15.55f64.to_radians().tan(),
        )
    }

    /// The Raspberry Pi Camera V2 sensor (Sony IMX219): 3280x2464, 3.04 mm lens, 1.12 um pixels.
    pub fn rpi_v2() -> Self {
        let f = 3.04e-3 / 1.12e-6;
        Self::centred(3280, 2464, f, f)
    }

    /// The Raspberry Pi Camera Module 3 Wide (Sony IMX708): 4608x2592, 2.75 mm lens, 1.4 um
    /// pixels (fx = fy = 1964 px), 120 deg diagonal field of view. A field that wide needs
    /// strong barrel distortion: k1 and k2 are chosen so that the 60 deg half-diagonal images
    /// onto the sensor's corner (1 + 3 k1 + 9 k2 = 0.777, k2 = 0.01) with the mapping monotonic
    /// out to it. A nominal lens, not a calibration.
    pub fn rpi_v3_wide() -> Self {
        let f = 2.75e-3 / 1.4e-6;
        let corner = (2304.0f64.hypot(1296.0) / f) / 60f64.to_radians().tan();
        let k2 = 0.01;
        let k1 = (corner - 1.0 - 9.0 * k2) / 3.0;
        Self {
            distortion: Distortion {
                k1,
                k2,
                ..Distortion::NONE
            },
            ..Self::centred(4608, 2592, f, f)
        }
    }

    /// A preset by name (see [`CAMERA_PRESETS`]).
    pub fn preset(name: &str) -> Option<Self> {
        match name {
            "paper" => Some(Self::paper()),
            "rpi-v2" => Some(Self::rpi_v2()),
            "rpi-v3-wide" => Some(Self::rpi_v3_wide()),
            _ => None,
        }
    }

    /// The same optics at another resolution (focal lengths and principal point scaled), e.g. a
    /// binned sensor mode.
    pub fn scaled_to(&self, width: u32, height: u32) -> Self {
        let sx = width as f64 / self.width as f64;
        let sy = height as f64 / self.height as f64;
        Self {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: (self.cx + 0.5) * sx - 0.5,
            cy: (self.cy + 0.5) * sy - 0.5,
            distortion: self.distortion,
            readout_s: self.readout_s,
        }
    }

    /// When row `v` (px, fractional rows allowed) was exposed, relative to the frame's instant
    /// (the middle row's mid-exposure), s: rows are read top to bottom over `readout_s`.
    pub fn row_time_s(&self, v: f64) -> f64 {
        if self.readout_s == 0.0 || self.height < 2 {
            return 0.0;
        }
        self.readout_s * (v / f64::from(self.height - 1) - 0.5)
    }

    /// Checks every field; the error names the field.
    pub fn validate(&self) -> Result<(), crate::InvalidField> {
        // Bounded, not just positive: buffer sizes and search windows are computed from these
        // (a 1e10 px focal length or a 4e9 px wide image would overflow them).
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if !(1..=MAX_SIDE_PX).contains(&v) {
                return Err(crate::InvalidField::new(
                    name,
                    format!("must be 1..={MAX_SIDE_PX} px, got {v}"),
                ));
            }
        }
        let side = f64::from(self.width.max(self.height));
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > 0.0 && v <= MAX_FOCAL_SIDES * side) {
                return Err(crate::InvalidField::new(
                    name,
                    format!("must be a positive number of px up to {MAX_FOCAL_SIDES} image widths, got {v}"),
                ));
            }
        }
        for (name, v) in [("cx", self.cx), ("cy", self.cy)] {
            if !(v.is_finite() && v.abs() <= 10.0 * side) {
                return Err(crate::InvalidField::new(
                    name,
                    format!("must be a finite number of px within 10 image widths, got {v}"),
                ));
            }
        }
        if !(self.readout_s.is_finite() && (0.0..=MAX_READOUT_S).contains(&self.readout_s)) {
            return Err(crate::InvalidField::new(
                "readout_s",
                format!("must be within 0..={MAX_READOUT_S} s, got {}", self.readout_s),
            ));
        }
        for (i, k) in self.distortion.to_array().iter().enumerate() {
            if !(k.is_finite() && k.abs() <= MAX_DISTORTION) {
                return Err(crate::InvalidField::new(
                    format!("distortion[{i}]"),
                    format!("must be finite and within +-{MAX_DISTORTION}, got {k}"),
                ));
            }
        }
        Ok(())
    }

    /// Pixel of a point in camera coordinates (x right, y down, z along the optical axis).
    /// None behind the camera.
    pub fn project(&self, p_cam: &Vector3<f64>) -> Option<[f64; 2]> {
        if !(p_cam.z > 0.0) {
            return None;
        }
        let [x, y] = self.distortion.apply([p_cam.x / p_cam.z, p_cam.y / p_cam.z]);
        Some([self.fx * x + self.cx, self.fy * y + self.cy])
    }

    /// Normalised, undistorted coordinates (x/z, y/z) of a pixel: the viewing ray is (x, y, 1).
    pub fn unproject(&self, [u, v]: [f64; 2]) -> Option<[f64; 2]> {
        self.distortion
            .remove([(u - self.cx) / self.fx, (v - self.cy) / self.fy])
    }

    /// Where the pixel would be without lens distortion (same fx, fy, cx, cy).
    pub fn undistort_pixel(&self, uv: [f64; 2]) -> Option<[f64; 2]> {
        if self.distortion.is_none() {
            return Some(uv);
        }
        let [x, y] = self.unproject(uv)?;
        Some([self.fx * x + self.cx, self.fy * y + self.cy])
    }

    /// Where an ideal (distortion-free) pixel appears through the lens: inverse of
    /// [`CameraModel::undistort_pixel`].
    pub fn distort_pixel(&self, [u, v]: [f64; 2]) -> [f64; 2] {
        let [x, y] = self
            .distortion
            .apply([(u - self.cx) / self.fx, (v - self.cy) / self.fy]);
        [self.fx * x + self.cx, self.fy * y + self.cy]
    }

    /// Undistorts many pixels in place; entries that do not invert become None.
    pub fn undistort_points(&self, points: &mut [Option<[f64; 2]>]) {
        for p in points.iter_mut() {
            *p = p.and_then(|uv| self.undistort_pixel(uv));
        }
    }

    /// True when the pixel position lies on the sensor (pixel edges at -0.5 and W - 0.5).
    pub fn contains(&self, [u, v]: [f64; 2]) -> bool {
        u >= -0.5 && v >= -0.5 && u < self.width as f64 - 0.5 && v < self.height as f64 - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn presets_match_notes() {
        let p = CameraModel::paper();
        // 3919.5 is sometimes quoted, but the formula 1640 / tan(22.7 deg) gives 3920.55.
        assert!((p.fx - 3920.546).abs() < 1e-3, "{}", p.fx);
        assert!((p.fy - 4427.4).abs() < 0.1, "{}", p.fy);
        assert_eq!((p.cx, p.cy), (1639.5, 1231.5));
        let r = CameraModel::rpi_v2();
        assert!((r.fx - 2714.29).abs() < 0.01 && r.fx == r.fy);
        assert!(CameraModel::preset("nope").is_none());
        for name in CAMERA_PRESETS {
            CameraModel::preset(name).unwrap().validate().unwrap();
        }
    }

    #[test]
    fn principal_axis_hits_principal_point() {
        let c = CameraModel::paper();
        let uv = c.project(&Vector3::new(0.0, 0.0, 5.0)).unwrap();
        assert_eq!(uv, [c.cx, c.cy]);
        assert!(c.project(&Vector3::new(0.0, 0.0, -1.0)).is_none());
        assert!(c.project(&Vector3::new(0.0, 0.0, 0.0)).is_none());
    }

    #[test]
    fn validate_names_the_field() {
        let mut c = CameraModel::rpi_v2();
        c.fy = -1.0;
        assert!(c.validate().unwrap_err().to_string().contains("`fy`"));
        c = CameraModel::rpi_v2();
        c.distortion.p2 = f64::NAN;
        assert!(c.validate().unwrap_err().to_string().contains("`distortion[3]`"));
    }

    #[test]
    fn scaling_keeps_the_field_of_view() {
        let c = CameraModel::rpi_v2();
        let s = c.scaled_to(640, 480);
        let p = Vector3::new(0.3, -0.2, 5.0);
        let a = c.project(&p).unwrap();
        let b = s.project(&p).unwrap();
        assert!(((a[0] + 0.5) * 640.0 / 3280.0 - 0.5 - b[0]).abs() < 1e-9);
        assert!(((a[1] + 0.5) * 480.0 / 2464.0 - 0.5 - b[1]).abs() < 1e-9);
    }

    fn lens() -> Distortion {
        // A plausible wide lens: barrel distortion plus a little decentring.
        Distortion::from_array([-0.28, 0.09, 1.2e-3, -8e-4, -0.012])
    }

    proptest! {
        #[test]
        fn undistort_inverts_distort(x in -0.6..0.6f64, y in -0.45..0.45f64) {
            let d = lens();
            let back = d.remove(d.apply([x, y])).unwrap();
            prop_assert!((back[0] - x).abs() < 1e-13 && (back[1] - y).abs() < 1e-13);
        }

        #[test]
        fn unproject_inverts_project(x in -0.5..0.5f64, y in -0.4..0.4f64, z in 0.5..20.0f64) {
            let mut c = CameraModel::rpi_v2();
            c.distortion = lens();
            let p = Vector3::new(x * z, y * z, z);
            let uv = c.project(&p).unwrap();
            let [nx, ny] = c.unproject(uv).unwrap();
            prop_assert!((nx - x).abs() < 1e-12 && (ny - y).abs() < 1e-12);
            let ideal = c.undistort_pixel(uv).unwrap();
            prop_assert!((ideal[0] - (c.fx * x + c.cx)).abs() < 1e-8);
            prop_assert!((ideal[1] - (c.fy * y + c.cy)).abs() < 1e-8);
        }
    }
}

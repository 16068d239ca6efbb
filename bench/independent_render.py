"""An independent renderer of the deck's markers (issue 71): frames made by code that shares none
of the simulator's assumptions, to measure deckwatch beside the OpenCV baseline on optics and
image pipelines the simulator (sim/src/render) did not generate.

Why: issue 71 reports that on another renderer's 640x480 frames deckwatch's full pose is
2.3-2.9x worse than a plain OpenCV pipeline, with a scale error, while on deckwatch's own frames
it is 2-4x better. This renderer was written only from the documented conventions
(docs/CONVENTIONS.md §1-§4 and §9, docs/recording.md "Recording format", docs/camera.md), not
from sim/src, so that its frames can tell whether the difference is in the optics or in a
shared convention. What it found: the optics. A lens blur of 2-3 px (deviation) at 640x480,
which the simulator's imaging family never ran (its lens blurs are held to about 1 px there),
made the full pose 1.2-2.3 times OpenCV's error, noise or none; the conventions agree to 0.01 px
(BENCHMARKS.md, "An independent renderer").

What it draws: the deck is the plane z = 0 of D (P_W = R P_D, R = Rx(roll) Ry(pitch) Rz(yaw) of
frames.csv's truth), seen by the camera of camera.json at C = (offset_x_m, offset_y_m, alt_m) in
W, p_cam = R_CW R_V^T (P_W - C) with R_CW = [[0,-1,0],[-1,0,0],[0,0,-1]] and R_V from the
vehicle_*_deg columns (identity when absent), pinhole with OpenCV's Brown-Conrady distortion
[k1, k2, p1, p2, k3], pixel centres at integer coordinates. Each marker of markers_deck_xyz_m is a
flat, uniformly bright disc of its radius (marker_radius_m; bow_marker_radius_m for index 1) on a
darker deck. A pixel's value is the share of its area inside the disc, measured by back-projecting
a grid of sub-sample rays (16 x 16 a pixel by default) through the camera model (distortion
inverted iteratively), intersecting the deck plane and testing each disc; only inside each
disc's image bounding box (from its projected rim, grown by the point spread's reach). The
scene is lit by a gentle linear gradient and a cos^4-like vignetting. A rolling shutter
(readout_ms) and motion during the exposure are not rendered (the frame's instant is its truth).

Imaging models (--model), all in linear light, then noise, then the image pipeline, then 8 bits:
  gauss    a Gaussian optical blur, sigma --blur-px (pixels at the output width): the plain case.
  airy     a non-Gaussian point spread, synthetic (no measured real-lens PSF with a clear licence
           was found): the PSF of a circular pupil computed by Fourier optics with a defocus of
           --defocus-waves and a coma of --coma-waves, Airy core radius --airy-px; rings, a
           defocus ring and a comatic tail toward +u.
  sharpen  the Gaussian blur, then an ISP's strong unsharp mask (--sharpen-amount, default 1.8,
           radius --sharpen-px 1.5) on the 8-bit image, clipped to 0..255 (halos, clipped tops).
  srgb     the Gaussian blur, then the sRGB transfer curve (piecewise: linear toe, 1/2.4 power).
  filmic   the Gaussian blur, then a filmic S-curve (a logistic in log exposure).
  jpeg     the Gaussian blur, then JPEG at --jpeg-quality (default 40).
  pillbox  geometric defocus: a uniform blur circle of radius --pillbox-px (a lens out of focus,
           diffraction left out); its edge is a circular segment's area, not a Gaussian's.
  bin      the sensor at --bin (2 or 4) times the output resolution: the blur at the sensor's
           resolution, shot and read noise per sensor pixel, 10-bit quantisation, then the
           binning's box average down to the output (as the Pi's 640x480 and 1640x1232 modes).
Every model adds seeded shot noise (--full-well electrons at full scale) and read noise
(--read-noise DN), deterministic per (--seed, frame index). Options compose (e.g. --model jpeg
--tone srgb --blur-px 2.5). Two options render a deliberate mismatch, to see what one does:
--pixel-origin 0.5 (a renderer whose pixel i spans [i, i + 1], against CONVENTIONS.md §3) and
--focal-scale SX,SY (the frames drawn with other focal lengths than camera.json's).
The `bin` model at 3280x2464 needs several GB (the sensor is drawn whole at 2x): use it at
640x480 and 1640x1232, the binned modes.

Usage (Python 3 with numpy and opencv; ci/peers.sh installs them):
  python3 bench/independent_render.py render SRC OUT [--model M] [options]
      SRC a recording made by `deckwatch sim record` (its camera.json and frames.csv truth are
      taken); OUT a new recording folder, same format, frames rendered here.
  python3 bench/independent_render.py check SRC OUT [--frames 0,10,20] [--png FILE]
      the rendered discs' intensity centroids beside their projected centres (cv2.projectPoints
      of the disc centre and of its rim's ellipse centre), and a side-by-side crop of SRC's frame
      and OUT's frame for a look.
  python3 bench/independent_render.py measure BINARY REC [REC...]
      `BINARY eval` and the OpenCV baseline (bench/opencv_pose_baseline.py) on each recording,
      one markdown row each: RMSE roll / pitch / yaw (deg) of the full pose and of OpenCV, their
      ratio, frames missed, the share of the full pose's errors within 2 stated sigma, and the
      slope (%, with its standard error) of the roll and pitch errors regressed on the true roll
      and pitch (issue 71's scale-error signature), the full pose's and OpenCV's. Writes
      REC-eval.csv and REC-opencv.csv beside each recording.

Example (640x480, a 2.5 px blur, little noise):
  deckwatch sim record --scenario ship --rate 2 --exposure-ms 4 --width 640 --height 480 \
      --frames 80 --seed 91 --out /tmp/ind/src640
  python3 bench/independent_render.py render /tmp/ind/src640 /tmp/ind/b25 --model gauss \
      --blur-px 2.5 --full-well 50000 --read-noise 0.5
  python3 bench/independent_render.py measure target/release/deckwatch /tmp/ind/src640 /tmp/ind/b25
"""
import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
# The baseline's elementary rotations (CONVENTIONS.md §2), the one other implementation here.
from opencv_pose_baseline import rot  # noqa: E402

cv2.setNumThreads(1)

R_CW = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
DECK_LEVEL = 0.22  # the deck's reflectance, linear, of full scale
DISC_LEVEL = 0.80  # the discs'


# ---------------------------------------------------------------------------------------------
# Geometry (CONVENTIONS.md §2, §3, §5)


def rpy_matrix_deg(roll, pitch, yaw):
    """R = Rx(roll) Ry(pitch) Rz(yaw), X-Y-Z (CONVENTIONS.md §2)."""
    return rot("x", math.radians(roll)) @ rot("y", math.radians(pitch)) @ rot("z", math.radians(yaw))


class Camera:
    def __init__(self, cam):
        self.w, self.h = int(cam["width"]), int(cam["height"])
        self.k = np.array([[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1]], dtype=np.float64)
        self.dist = np.array(cam.get("distortion", [0, 0, 0, 0, 0]), dtype=np.float64)
        self.distorted = bool(np.any(self.dist != 0))

    def normalised(self, u, v):
        """Pixel coordinates (arrays) -> normalised image coordinates x/z, y/z (distortion inverted)."""
        if not self.distorted:
            return (u - self.k[0, 2]) / self.k[0, 0], (v - self.k[1, 2]) / self.k[1, 1]
        pts = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2).astype(np.float64)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        n = cv2.undistortPointsIter(pts, self.k, self.dist, None, None, crit).reshape(-1, 2)
        return n[:, 0].reshape(u.shape), n[:, 1].reshape(u.shape)


class Pose:
    """One frame's truth: the deck's attitude R in W, the camera at C, the vehicle's R_V."""

    def __init__(self, row):
        self.r = rpy_matrix_deg(float(row["roll_deg"]), float(row["pitch_deg"]), float(row["yaw_deg"]))
        self.c = np.array([float(row.get("offset_x_m") or 0), float(row.get("offset_y_m") or 0), float(row["alt_m"])])
        veh = [row.get(c) for c in ("vehicle_roll_deg", "vehicle_pitch_deg", "vehicle_yaw_deg")]
        self.r_v = rpy_matrix_deg(*map(float, veh)) if all(v not in (None, "", "nan") for v in veh) else np.eye(3)
        # camera from deck: p_cam = R_CW R_V^T (R P_D - C)
        self.r_cd = R_CW @ self.r_v.T @ self.r
        self.t_cd = -R_CW @ self.r_v.T @ self.c

    def rvec_tvec(self):
        rvec, _ = cv2.Rodrigues(self.r_cd)
        return rvec, self.t_cd.reshape(3, 1)

    def deck_points(self, xn, yn):
        """Rays through normalised image points -> their intersections with the deck, in D (x, y)."""
        # ray in the camera (x, y, 1), in D: R_cd^T d; camera centre in D: -R_cd^T t
        rt = self.r_cd.T
        o = -rt @ self.t_cd
        dx = rt[0, 0] * xn + rt[0, 1] * yn + rt[0, 2]
        dy = rt[1, 0] * xn + rt[1, 1] * yn + rt[1, 2]
        dz = rt[2, 0] * xn + rt[2, 1] * yn + rt[2, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = -o[2] / dz
        t = np.where(t > 0, t, np.nan)  # behind the camera: no deck
        return o[0] + t * dx, o[1] + t * dy


def markers(deck):
    out = []
    for i, xyz in enumerate(deck["markers_deck_xyz_m"]):
        r = deck["bow_marker_radius_m"] if i == 1 else deck["marker_radius_m"]
        out.append((np.array(xyz, dtype=np.float64), float(r)))
    return out


def project(cam, pose, pts):
    rvec, tvec = pose.rvec_tvec()
    px, _ = cv2.projectPoints(np.asarray(pts, dtype=np.float64).reshape(-1, 3), rvec, tvec, cam.k, cam.dist)
    return px.reshape(-1, 2)


def rim(centre, radius, n=128):
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a), np.full_like(a, centre[2])], axis=1)


# ---------------------------------------------------------------------------------------------
# Point spreads, sampled on a grid of `step` output pixels (normalised to sum 1)


def gaussian_psf(sigma_px, step):
    s = sigma_px / step
    r = max(1, int(math.ceil(4 * s)))
    x = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-0.5 * (x / s) ** 2) if s > 0 else (x == 0).astype(np.float64)
    k = np.outer(g, g)
    return k / k.sum()


def pillbox_psf(radius_px, step):
    """Geometric defocus: a uniform disc of `radius_px` output pixels (the blur circle of a lens
    out of focus, without diffraction), sampled every `step` output pixels, each sample the share
    of its cell inside the disc (8 x 8 sub-samples): a flat-topped spread with a hard rim. Its
    edge response is a circular segment's area with kinks at the rim's reach, not an error
    function."""
    r = radius_px / step
    if r < 0.5:  # a circle smaller than a grid cell: no blur (as gaussian_psf's sigma 0)
        return np.ones((1, 1))
    n = max(1, int(math.ceil(r)) + 1)
    sub = (np.arange(8) + 0.5) / 8 - 0.5
    x = (np.arange(-n, n + 1, dtype=np.float64)[:, None] + sub[None, :]).ravel()
    inside = (x[:, None] ** 2 + x[None, :] ** 2 <= r * r).astype(np.float64)
    k = inside.reshape(2 * n + 1, 8, 2 * n + 1, 8).mean(axis=(1, 3))
    return k / k.sum()


def pupil_psf(airy_px, defocus_waves, coma_waves, step):
    """|FT(pupil)|^2 of a circular pupil with defocus W020 rho^2 and coma W131 rho^3 cos(theta)
    (toward +u), sampled every `step` output pixels. The Airy core's first zero is at airy_px.
    Synthetic: a stand-in for a measured real-lens PSF."""
    n = 512
    # FT sampling: with the pupil of diameter D samples in an n grid, the PSF's sample is
    # lambda/(n * du); the first zero of the Airy pattern is 1.22 n / D samples.
    zero_samples = airy_px / step
    d = 1.22 * n / zero_samples
    y, x = (np.mgrid[0:n, 0:n] - n / 2) / (d / 2)
    rho2 = x * x + y * y
    inside = rho2 <= 1.0
    w = defocus_waves * (2 * rho2 - 1) + coma_waves * (3 * rho2 - 2) * np.sqrt(rho2) * x / np.maximum(np.sqrt(rho2), 1e-12)
    field = np.where(inside, np.exp(2j * np.pi * w), 0)
    psf = np.abs(np.fft.fftshift(np.fft.fft2(np.fft.ifftshift(field)))) ** 2
    # keep 99 % of the energy in a square window about the centre (the diffraction halo's far
    # rings hold the rest)
    c = n // 2
    total = psf.sum()
    for r in range(2, c):
        if psf[c - r : c + r + 1, c - r : c + r + 1].sum() >= 0.99 * total:
            break
    k = psf[c - r : c + r + 1, c - r : c + r + 1]
    return k / k.sum()


# ---------------------------------------------------------------------------------------------
# Rendering


def illumination(cam, u, v, gradient, vignetting):
    """A gentle light: a linear gradient across the frame and a cos^4-like falloff."""
    w, h = cam.w, cam.h
    x = (u - 0.5 * (w - 1)) / w
    y = (v - 0.5 * (h - 1)) / h
    r2 = (x * x + y * y) / 0.5  # 1 at the corners
    return (1.0 + gradient * (0.8 * x + 0.6 * y)) * (1.0 - vignetting * r2)


def render_frame(cam, deck, pose, a, psf, sensor):
    """Linear radiance at the sensor's resolution (`sensor` times the output's), float64, with the
    optical point spread applied to the discs (the deck's light is smooth: a normalised PSF
    leaves it as it is)."""
    s = sensor
    sw, sh = cam.w * s, cam.h * s
    # a sensor pixel (i, j) at s x: its centre in output pixels is (j + 0.5) / s - 0.5
    uo = ((np.arange(sw, dtype=np.float64) + 0.5) / s - 0.5)[None, :]
    vo = ((np.arange(sh, dtype=np.float64) + 0.5) / s - 0.5)[:, None]
    light = illumination(cam, uo, vo, a.gradient, a.vignetting)
    img = DECK_LEVEL * light
    # the PSF on the oversampled grid (`o` samples per sensor pixel), then averaged to the sensor
    o = a.oversample
    step = 1.0 / (s * o)
    reach = (psf.shape[0] // 2 + 1) * step + 2.0  # in output px
    n_sub = max(1, a.supersample // (s * o))  # sub-samples per side of an oversampled cell
    for centre, radius in markers(deck):
        px = project(cam, pose, rim(centre, radius))
        if not np.all(np.isfinite(px)):
            continue
        u0, v0 = np.floor(px.min(axis=0) - reach).astype(int)
        u1, v1 = np.ceil(px.max(axis=0) + reach).astype(int)
        u0, v0, u1, v1 = max(u0, 0), max(v0, 0), min(u1, cam.w - 1), min(v1, cam.h - 1)
        if u1 < u0 or v1 < v0:
            continue
        # the oversampled cells of the box: sensor pixels [u0*s, (u1+1)*s), each o x o cells
        nu, nv = (u1 - u0 + 1) * s * o, (v1 - v0 + 1) * s * o
        # sub-sample offsets inside a cell, in cells
        sub = (np.arange(n_sub) + 0.5) / n_sub
        cu = np.arange(nu, dtype=np.float64)
        cv = np.arange(nv, dtype=np.float64)
        # output coordinate of the cell's sub-samples: u0 - 0.5 + (cell + sub) * step
        # (--pixel-origin 0.5: a renderer that takes pixel i to span [i, i + 1])
        su = u0 - 0.5 + a.pixel_origin + (cu[:, None] + sub[None, :]).ravel() * step
        sv = v0 - 0.5 + a.pixel_origin + (cv[:, None] + sub[None, :]).ravel() * step
        gu, gv = np.meshgrid(su, sv)
        xn, yn = cam.normalised(gu, gv)
        dx, dy = pose.deck_points(xn, yn)
        inside = ((dx - centre[0]) ** 2 + (dy - centre[1]) ** 2 <= radius * radius).astype(np.float64)
        cover = inside.reshape(nv, n_sub, nu, n_sub).mean(axis=(1, 3))  # per oversampled cell
        # the disc's light above the deck's, lit
        cgu = u0 - 0.5 + a.pixel_origin + (cu + 0.5) * step
        cgv = v0 - 0.5 + a.pixel_origin + (cv + 0.5) * step
        lu, lv = np.meshgrid(cgu, cgv)
        excess = (DISC_LEVEL - DECK_LEVEL) * cover * illumination(cam, lu, lv, a.gradient, a.vignetting)
        # the point spread (zero beyond the box: the box is grown by its reach)
        excess = cv2.filter2D(excess, -1, psf[::-1, ::-1].copy(), borderType=cv2.BORDER_CONSTANT)
        # to sensor pixels
        excess = excess.reshape(nv // o, o, nu // o, o).mean(axis=(1, 3))
        img[v0 * s : (v1 + 1) * s, u0 * s : (u1 + 1) * s] += excess
    return img


def srgb(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def filmic(x):
    """A filmic S-curve: a logistic in log2 exposure about middle grey 0.18, toe and shoulder,
    rescaled so that 0 -> 0 and 1 -> 1."""
    x = np.clip(x, 1e-6, 1)
    f = lambda t: 1.0 / (1.0 + np.exp(-1.4 * (np.log2(t / 0.18))))
    lo, hi = f(np.float64(1e-6)), f(np.float64(1.0))
    return (f(x) - lo) / (hi - lo)


def image_pipeline(lin, a, rng):
    """Linear light at the sensor -> noisy 8-bit output frame."""
    s = a.bin
    x = np.clip(lin, 0, None)
    if a.full_well > 0:
        x = rng.poisson(x * a.full_well) / a.full_well
    if a.read_noise > 0:
        x = x + rng.normal(0.0, a.read_noise / 255.0, x.shape)
    if s > 1:
        x = np.round(np.clip(x, 0, 1) * 1023) / 1023  # the sensor's 10-bit raw
        h, w = x.shape[0] // s, x.shape[1] // s
        x = x.reshape(h, s, w, s).mean(axis=(1, 3))
    if a.tone == "srgb":
        x = srgb(x)
    elif a.tone == "filmic":
        x = filmic(x)
    y = np.clip(x, 0, 1) * 255.0
    if a.sharpen_amount > 0:
        y8 = np.round(np.clip(y, 0, 255))
        blur = cv2.GaussianBlur(y8, (0, 0), a.sharpen_px)
        y = y8 + a.sharpen_amount * (y8 - blur)
    out = np.round(np.clip(y, 0, 255)).astype(np.uint8)
    if a.jpeg_quality > 0:
        ok, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, a.jpeg_quality])
        out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    return out


MODELS = {
    "gauss": {},
    "airy": {"psf": "airy"},
    "sharpen": {"sharpen_amount": 1.8},
    "srgb": {"tone": "srgb"},
    "filmic": {"tone": "filmic"},
    "jpeg": {"jpeg_quality": 40},
    "bin": {"bin": 2},
    "pillbox": {"psf": "pillbox"},
}


def render(a):
    cam_json = json.load(open(os.path.join(a.src, "camera.json")))
    cam = Camera(cam_json)
    if a.focal_scale:
        sx, sy = (float(x) for x in a.focal_scale.split(","))
        cam.k[0, 0] *= sx
        cam.k[1, 1] *= sy
    if float(cam_json.get("readout_ms", 0) or 0) != 0:
        print("note: readout_ms is not rendered (a global shutter is drawn)", file=sys.stderr)
    deck = cam_json["deck"]
    preset = MODELS[a.model]
    for key, val in preset.items():
        if getattr(a, key) is None:
            setattr(a, key, val)
    defaults = {"psf": "gauss", "sharpen_amount": 0.0, "tone": "linear", "jpeg_quality": 0, "bin": 1}
    for key, val in defaults.items():
        if getattr(a, key) is None:
            setattr(a, key, val)
    s = a.bin
    step = 1.0 / (s * a.oversample)
    if a.psf == "airy":
        psf = pupil_psf(a.airy_px, a.defocus_waves, a.coma_waves, step)
    elif a.psf == "pillbox":
        psf = pillbox_psf(a.pillbox_px, step)
    else:
        psf = gaussian_psf(a.blur_px, step)
    os.makedirs(os.path.join(a.out, "frames"), exist_ok=True)
    shutil.copy(os.path.join(a.src, "camera.json"), os.path.join(a.out, "camera.json"))
    rows = list(csv.DictReader(open(os.path.join(a.src, "frames.csv"))))
    if a.frames:
        rows = rows[: a.frames]
    with open(os.path.join(a.out, "frames.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        for row in rows:
            idx = int(row["index"])
            rng = np.random.default_rng([a.seed, idx])
            if row["roll_deg"] in ("", "nan", "NaN"):
                lin = np.full((cam.h * s, cam.w * s), DECK_LEVEL)
            else:
                lin = render_frame(cam, deck, Pose(row), a, psf, s)
            img = image_pipeline(lin, a, rng)
            name = f"frames/{idx:06d}.png"
            cv2.imwrite(os.path.join(a.out, name), img)
            row = dict(row)
            row["file"] = name
            w.writerow(row)
    with open(os.path.join(a.out, "independent_render.json"), "w") as f:
        json.dump({k: v for k, v in vars(a).items() if k not in ("func",)}, f, indent=1)


# ---------------------------------------------------------------------------------------------
# Check


def centroid(img, p, r_px):
    """Background-subtracted intensity centroid in a window of radius 2 r_px + 4 about p."""
    h = int(math.ceil(2 * r_px + 4))
    x0, y0 = int(round(p[0])) - h, int(round(p[1])) - h
    roi = img[y0 : y0 + 2 * h + 1, x0 : x0 + 2 * h + 1].astype(np.float64)
    border = np.concatenate([roi[0], roi[-1], roi[:, 0], roi[:, -1]])
    wts = np.clip(roi - np.median(border), 0, None)
    yy, xx = np.mgrid[0 : roi.shape[0], 0 : roi.shape[1]]
    return np.array([x0 + (wts * xx).sum() / wts.sum(), y0 + (wts * yy).sum() / wts.sum()])


def check(a):
    cam_json = json.load(open(os.path.join(a.out, "camera.json")))
    cam = Camera(cam_json)
    deck = cam_json["deck"]
    src_rows = {r["index"]: r for r in csv.DictReader(open(os.path.join(a.src, "frames.csv")))}
    out_rows = {r["index"]: r for r in csv.DictReader(open(os.path.join(a.out, "frames.csv")))}
    crops = []
    print("frame marker | centroid - image of centre (px) | centroid - rim ellipse centre (px) | SRC's frame (deckwatch's render): centroid - rim ellipse centre")
    for fi in a.check_frames.split(","):
        row = out_rows[fi]
        pose = Pose(row)
        ours = cv2.imread(os.path.join(a.out, row["file"]), cv2.IMREAD_GRAYSCALE)
        theirs = cv2.imread(os.path.join(a.src, src_rows[fi]["file"]), cv2.IMREAD_GRAYSCALE)
        for i, (centre, radius) in enumerate(markers(deck)):
            c_px = project(cam, pose, [centre])[0]
            (ex, ey), _, _ = cv2.fitEllipse(project(cam, pose, rim(centre, radius)).astype(np.float32))
            r_px = radius * cam.k[0, 0] / pose.c[2]
            mo = centroid(ours, c_px, r_px)
            mt = centroid(theirs, c_px, r_px)
            print(f"{fi:>5} {i} | {mo[0] - c_px[0]:+.3f} {mo[1] - c_px[1]:+.3f} | {mo[0] - ex:+.3f} {mo[1] - ey:+.3f} "
                  f"| {mt[0] - ex:+.3f} {mt[1] - ey:+.3f}")
        # a crop about the bow marker, both frames, 6x nearest-neighbour
        c = project(cam, pose, [deck["markers_deck_xyz_m"][1]])[0]
        half = int(3 * deck["bow_marker_radius_m"] * cam.k[0, 0] / pose.c[2]) + 4
        x0, y0 = int(c[0]) - half, int(c[1]) - half
        pair = [im[y0 : y0 + 2 * half, x0 : x0 + 2 * half] for im in (theirs, ours)]
        zoom = max(1, 240 // (2 * half))
        pair = [cv2.resize(p, None, fx=zoom, fy=zoom, interpolation=cv2.INTER_NEAREST) for p in pair]
        crops.append(np.hstack([pair[0], np.full((pair[0].shape[0], 6), 255, np.uint8), pair[1]]))
    if a.png:
        # the crops, one frame a row; and the first frame whole, side by side (PNG-full.png)
        wmax = max(c.shape[1] for c in crops)
        crops = [np.pad(c, ((0, 6), (0, wmax - c.shape[1])), constant_values=255) for c in crops]
        cv2.imwrite(a.png, np.vstack(crops))
        fi = a.check_frames.split(",")[0]
        full = [cv2.imread(os.path.join(d, r[fi]["file"]), cv2.IMREAD_GRAYSCALE) for d, r in ((a.src, src_rows), (a.out, out_rows))]
        cv2.imwrite(a.png.replace(".png", "-full.png"), np.hstack([full[0], np.full((full[0].shape[0], 8), 255, np.uint8), full[1]]))
        print(f"crops (left: SRC, right: OUT): {a.png}")


# ---------------------------------------------------------------------------------------------
# Measure


def slope_pct(x, y):
    """Least-squares slope of y on x (with an intercept), in % (100 dy/dx), and its standard error."""
    x, y = np.asarray(x), np.asarray(y)
    if len(x) < 3:
        return float("nan"), float("nan")
    xm = x - x.mean()
    b = (xm * (y - y.mean())).sum() / (xm * xm).sum()
    res = y - y.mean() - b * xm
    se = math.sqrt((res * res).sum() / (len(x) - 2) / (xm * xm).sum())
    return 100 * b, 100 * se


def measure_one(binary, rec):
    import opencv_pose_baseline  # noqa: E402
    from imaging_models import full_pose_errors, rmse  # noqa: E402

    eval_csv = rec.rstrip("/") + "-eval.csv"
    subprocess.run([binary, "eval", rec, "--csv", eval_csv], check=True, stdout=subprocess.DEVNULL)
    ours, estimates, missed, inside, counted = full_pose_errors(eval_csv)
    truth = [[est[i] - e[i] for i in range(3)] for e, est in zip(ours, estimates)]
    base_csv = rec.rstrip("/") + "-opencv.csv"
    with open(base_csv, "w", newline="") as f:
        opencv_pose_baseline.evaluate(rec, csv.writer(f))
    truth_of = {r["index"]: r for r in csv.DictReader(open(os.path.join(rec, "frames.csv")))}
    theirs, their_truth, their_missed = [], [], 0
    for r in csv.DictReader(open(base_csv), fieldnames=["recording", "index", "valid", "r", "p", "y"]):
        if r["valid"] == "1":
            theirs.append([float(r[c]) for c in ("r", "p", "y")])
            their_truth.append([float(truth_of[r["index"]][c]) for c in ("roll_deg", "pitch_deg")])
        else:
            their_missed += 1
    o = [rmse(ours, i) for i in range(3)]
    t = [rmse(theirs, i) for i in range(3)]
    ratio = [o[i] / t[i] if t[i] > 0 else float("nan") for i in range(3)]
    share = [100 * inside[i] / counted if counted else float("nan") for i in range(3)]
    e, tr = np.array(ours), np.array(truth)
    sr = slope_pct(tr[:, 0], e[:, 0]) if len(e) else (math.nan, math.nan)
    sp = slope_pct(tr[:, 1], e[:, 1]) if len(e) else (math.nan, math.nan)
    e, tr = np.array(theirs), np.array(their_truth)
    osr = slope_pct(tr[:, 0], e[:, 0]) if len(e) else (math.nan, math.nan)
    osp = slope_pct(tr[:, 1], e[:, 1]) if len(e) else (math.nan, math.nan)
    return o, t, ratio, missed, their_missed, share, sr, sp, osr, osp


def measure(a):
    print("| recording | full pose RMSE r / p / y (deg) | OpenCV RMSE r / p / y | ratio r / p / y | missed (ours / OpenCV) "
          "| within 2 sigma r / p / y | slope err~truth roll / pitch (% +- se) | OpenCV's slope roll / pitch |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for rec in a.recordings:
        o, t, ratio, m, tm, share, sr, sp, osr, osp = measure_one(a.binary, rec)
        print(f"| {os.path.basename(rec.rstrip('/'))} | {o[0]:.4f} / {o[1]:.4f} / {o[2]:.4f} | {t[0]:.4f} / {t[1]:.4f} / {t[2]:.4f} "
              f"| {ratio[0]:.2f} / {ratio[1]:.2f} / {ratio[2]:.2f} | {m} / {tm} | {share[0]:.0f} / {share[1]:.0f} / {share[2]:.0f} % "
              f"| {sr[0]:+.2f} +- {sr[1]:.2f} / {sp[0]:+.2f} +- {sp[1]:.2f} | {osr[0]:+.2f} +- {osr[1]:.2f} / {osp[0]:+.2f} +- {osp[1]:.2f} |")
        sys.stdout.flush()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render", help="render a recording's truth into a new recording")
    r.add_argument("src")
    r.add_argument("out")
    r.add_argument("--model", choices=sorted(MODELS), default="gauss")
    r.add_argument("--frames", type=int, default=0, help="only the first N frames (0 = all)")
    r.add_argument("--seed", type=int, default=1, help="the noise's seed")
    r.add_argument("--supersample", type=int, default=16, help="sub-samples per output pixel and side")
    r.add_argument("--oversample", type=int, default=4, help="PSF grid cells per sensor pixel and side")
    r.add_argument("--blur-px", type=float, default=1.0, help="Gaussian sigma (output pixels)")
    r.add_argument("--psf", choices=["gauss", "airy", "pillbox"], default=None)
    r.add_argument("--airy-px", type=float, default=1.0, help="Airy first zero radius (output pixels)")
    r.add_argument("--pillbox-px", type=float, default=4.0, help="pillbox: the blur circle's radius (output pixels)")
    r.add_argument("--defocus-waves", type=float, default=0.4, help="defocus W020 (waves)")
    r.add_argument("--coma-waves", type=float, default=0.25, help="coma W131 (waves, tail toward +u)")
    r.add_argument("--pixel-origin", type=float, default=0.0,
                   help="0: pixel centres at integer coordinates (CONVENTIONS.md §3); 0.5: a renderer with "
                        "pixel i spanning [i, i + 1] (a half-pixel convention error, for testing)")
    r.add_argument("--sharpen-amount", type=float, default=None)
    r.add_argument("--sharpen-px", type=float, default=1.5)
    r.add_argument("--tone", choices=["linear", "srgb", "filmic"], default=None)
    r.add_argument("--jpeg-quality", type=int, default=None)
    r.add_argument("--bin", type=int, default=None, help="sensor pixels binned per output pixel and side")
    r.add_argument("--focal-scale", default="", metavar="SX,SY",
                   help="render with fx, fy scaled (camera.json is copied unchanged): a calibration that "
                        "does not match the camera, for testing")
    r.add_argument("--gradient", type=float, default=0.12, help="illumination gradient across the frame")
    r.add_argument("--vignetting", type=float, default=0.15, help="light lost in the corners")
    r.add_argument("--full-well", type=float, default=2000.0, help="electrons at full scale (0 = no shot noise)")
    r.add_argument("--read-noise", type=float, default=1.5, help="read noise, DN of 255")
    r.set_defaults(func=render)
    c = sub.add_parser("check", help="rendered centres vs truth, and a side-by-side crop")
    c.add_argument("src")
    c.add_argument("out")
    c.add_argument("--frames", dest="check_frames", default="0,10,20")
    c.add_argument("--png", default=None)
    c.set_defaults(func=check)
    m = sub.add_parser("measure", help="deckwatch eval and the OpenCV baseline, with the scale-error slope")
    m.add_argument("binary")
    m.add_argument("recordings", nargs="+")
    m.set_defaults(func=measure)
    a = ap.parse_args()
    a.func(a)


if __name__ == "__main__":
    main()

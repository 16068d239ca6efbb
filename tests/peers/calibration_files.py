"""Calibration files as other tools write them, and OpenCV's own projections through them, for
tests/calibration_import.rs.

Usage: calibration_files.py OUT_DIR

Writes into OUT_DIR:
- OpenCV FileStorage YAML and XML, written by cv2.FileStorage itself (the real writer);
- ROS camera_info YAML in camera_calibration_parsers' documented layout (plumb_bob and
  rational_polynomial);
- Kalibr camchains (two radtan cameras; a moderate equidistant lens that Brown-Conrady fits; a
  wide equidistant lens that it cannot);
- bad files: NaN and a 3x4 camera matrix through cv2.FileStorage, a non-identity rectification,
  nonzero rational k4..k6, a missing camera_matrix, an omni camera.

Prints JSON: {"cases": [{name, file, args, points, pixels}], "bad": {name: file}} where
`pixels` are cv2.projectPoints' (cv2.fisheye.projectPoints' for equidistant) pixels of
`points` (camera frame, m), each inside the image.
"""

import json
import os
import sys

import cv2
import numpy as np


def points_in_view(width, height, fx, fy, cx, cy, count, seed):
    """3D points (camera frame) whose undistorted pixels spread over the image."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(0.02 * width, 0.98 * width, count)
    v = rng.uniform(0.02 * height, 0.98 * height, count)
    z = rng.uniform(1.5, 12.0, count)
    x = (u - cx) / fx * z
    y = (v - cy) / fy * z
    return np.stack([x, y, z], axis=1)


def inside(pixels, width, height):
    return (
        (pixels[:, 0] >= -0.5)
        & (pixels[:, 0] <= width - 0.5)
        & (pixels[:, 1] >= -0.5)
        & (pixels[:, 1] <= height - 0.5)
    )


def camera_matrix(fx, fy, cx, cy):
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def project(points, k, d, fisheye=False):
    zero = np.zeros(3)
    if fisheye:
        pixels, _ = cv2.fisheye.projectPoints(points.reshape(-1, 1, 3), zero, zero, k, d)
    else:
        pixels, _ = cv2.projectPoints(points, zero, zero, k, d)
    return pixels.reshape(-1, 2)


def case(name, path, args, size, k, d, fisheye=False, seed=1):
    width, height = size
    points = points_in_view(width, height, k[0, 0], k[1, 1], k[0, 2], k[1, 2], 60, seed)
    pixels = project(points, k, np.asarray(d, dtype=np.float64), fisheye)
    keep = inside(pixels, width, height)
    assert keep.sum() >= 20, f"{name}: too few points in view"
    return {
        "name": name,
        "file": path,
        "args": args,
        "points": points[keep].tolist(),
        "pixels": pixels[keep].tolist(),
    }


def rounded(values, decimals=8):
    """Values as a file with this many decimals holds them (the projection uses the same)."""
    return [float(f"{v:.{decimals}f}") for v in values]


def fmt(values, decimals=8):
    return "[" + ", ".join(f"{v:.{decimals}f}" for v in values) + "]"


def ros_camera_info(name, size, k, model, d, rectification=None, projection=None):
    """camera_calibration_parsers' layout (the keys of sensor_msgs/CameraInfo)."""
    width, height = size
    r = rectification if rectification is not None else [1, 0, 0, 0, 1, 0, 0, 0, 1]
    p = projection if projection is not None else list(k[0]) + [0.0] + list(k[1]) + [0.0] + list(k[2]) + [0.0]
    return (
        f"image_width: {width}\n"
        f"image_height: {height}\n"
        f"camera_name: {name}\n"
        "camera_matrix:\n  rows: 3\n  cols: 3\n"
        f"  data: {fmt(k.flatten())}\n"
        f"distortion_model: {model}\n"
        f"distortion_coefficients:\n  rows: 1\n  cols: {len(d)}\n  data: {fmt(d)}\n"
        f"rectification_matrix:\n  rows: 3\n  cols: 3\n  data: {fmt(r)}\n"
        f"projection_matrix:\n  rows: 3\n  cols: 4\n  data: {fmt(p)}\n"
    )


def kalibr_camera(name, model, intrinsics, distortion_model, coeffs, size, extra=""):
    return (
        f"{name}:\n"
        f"  camera_model: {model}\n"
        f"  intrinsics: {fmt(intrinsics)}\n"
        f"  distortion_model: {distortion_model}\n"
        f"  distortion_coeffs: {fmt(coeffs)}\n"
        f"{extra}"
        f"  resolution: [{size[0]}, {size[1]}]\n"
        f"  rostopic: /{name}/image_raw\n"
    )


def write(out, name, text):
    path = os.path.join(out, name)
    with open(path, "w") as f:
        f.write(text)
    return path


def opencv_file(path, size, k, d):
    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
    if size is not None:
        # The keys OpenCV's calibration sample (camera_calibration.cpp) writes.
        fs.write("image_width", size[0])
        fs.write("image_height", size[1])
    fs.write("camera_matrix", k)
    fs.write("distortion_coefficients", np.asarray(d, dtype=np.float64))
    fs.release()
    return path


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    cases = []
    bad = {}

    # OpenCV YAML: the calibration sample's keys, a 5x1 Brown-Conrady vector.
    size = (1640, 1232)
    k = camera_matrix(1300.1428, 1300.7113, 819.4752, 615.1992)
    d = np.array([[0.19205], [-0.52541], [1.2e-4], [-3.1e-4], [0.43119]])
    path = opencv_file(os.path.join(out, "opencv.yml"), size, k, d)
    cases.append(case("opencv_yaml", path, [], size, k, d.ravel()))

    # OpenCV XML without the image size, an 8-coefficient (rational) vector with k4..k6 zero.
    size = (640, 480)
    k = camera_matrix(512.31, 511.87, 318.92, 241.35)
    d = np.array([[-0.21, 0.08, 6e-4, -4e-4, -0.012, 0.0, 0.0, 0.0]])
    path = opencv_file(os.path.join(out, "opencv.xml"), None, k, d)
    cases.append(case("opencv_xml", path, ["--image-size", "640x480"], size, k, d.ravel(), seed=2))
    bad["opencv_xml_no_size"] = path

    # ROS camera_info: plumb_bob, and rational_polynomial with k4..k6 zero.
    size = (1280, 720)
    k = camera_matrix(*rounded([911.82233, 912.50107, 641.7382, 362.11294]))
    d = rounded([0.11021, -0.24012, 0.00143, -0.00087, 0.11873])
    path = write(out, "ros_plumb_bob.yaml", ros_camera_info("narrow_stereo", size, k, "plumb_bob", d))
    cases.append(case("ros_plumb_bob", path, [], size, k, d, seed=3))
    d8 = rounded([-0.29, 0.09, -0.0011, 0.00042, -0.013, 0.0, 0.0, 0.0])
    path = write(out, "ros_rational.yaml", ros_camera_info("wide", size, k, "rational_polynomial", d8))
    cases.append(case("ros_rational", path, ["--camera", "wide"], size, k, d8, seed=4))

    # Kalibr: two radtan cameras (choose cam1), then a moderate equidistant lens.
    t_imu = "  T_cam_imu:\n" + "".join(
        f"  - {fmt(row)}\n" for row in [[0, 1, 0, 0.07], [-1, 0, 0, -0.02], [0, 0, 1, 0.004], [0, 0, 0, 1]]
    )
    cam0 = rounded([461.629, 460.152, 362.680, 246.049])
    cam1 = rounded([458.654, 457.296, 367.215, 248.375])
    d1 = rounded([-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05])
    text = kalibr_camera("cam0", "pinhole", cam0, "radtan", [-0.27695497, 0.06712482, 0.00087538, 0.00011556],
                         (752, 480), t_imu)
    text += kalibr_camera("cam1", "pinhole", cam1, "radtan", d1, (752, 480),
                          "  T_cn_cnm1:\n" + "".join(f"  - {fmt(r)}\n" for r in np.eye(4).tolist())
                          + "  cam_overlaps: [0]\n")
    path = write(out, "kalibr_radtan.yaml", text)
    cases.append(case("kalibr_radtan", path, ["--camera", "cam1"], (752, 480),
                      camera_matrix(*cam1), d1, seed=5))
    fisheye = rounded([820.0, 818.0, 322.3, 237.9])
    kd = rounded([0.02, -0.01, 0.005, -0.002])
    path = write(out, "kalibr_equidistant.yaml",
                 kalibr_camera("cam0", "pinhole", fisheye, "equidistant", kd, (640, 480), t_imu))
    cases.append(case("kalibr_equidistant", path, [], (640, 480), camera_matrix(*fisheye), kd,
                      fisheye=True, seed=6))

    # Refused or broken files.
    bad["kalibr_wide"] = write(out, "kalibr_wide.yaml", kalibr_camera(
        "cam0", "pinhole", [461.629, 460.152, 362.680, 246.049], "equidistant",
        [-0.01316, 0.05008, -0.04506, 0.01241], (752, 480)))
    bad["kalibr_omni"] = write(out, "kalibr_omni.yaml", kalibr_camera(
        "cam0", "omni", [0.80065662, 833.006, 830.345, 373.850, 253.749], "radtan",
        [-0.3351875, 0.13211436, 0.00055967, 0.00057686], (752, 480)))
    k = camera_matrix(np.nan, 500.0, 320.0, 240.0)
    bad["opencv_yaml_nan"] = opencv_file(os.path.join(out, "opencv_nan.yml"), (640, 480), k, np.zeros((5, 1)))
    k34 = np.hstack([camera_matrix(500.0, 500.0, 320.0, 240.0), np.zeros((3, 1))])
    bad["opencv_xml_3x4"] = opencv_file(os.path.join(out, "opencv_3x4.xml"), (640, 480), k34, np.zeros((1, 5)))
    k = camera_matrix(500.0, 500.0, 320.0, 240.0)
    bad["ros_stereo"] = write(out, "ros_stereo.yaml", ros_camera_info(
        "left", (640, 480), k, "plumb_bob", [0.0] * 5,
        rectification=[0.9998, 0.0175, 0.0, -0.0175, 0.9998, 0.0, 0.0, 0.0, 1.0]))
    bad["ros_rational_k5"] = write(out, "ros_rational_k5.yaml", ros_camera_info(
        "wide", (640, 480), k, "rational_polynomial", [-0.29, 0.09, 0.0, 0.0, -0.013, 0.0, 0.02, 0.0]))
    text = ros_camera_info("narrow", (640, 480), k, "plumb_bob", [0.0] * 5)
    start = text.index("camera_matrix:")
    end = text.index("distortion_model:")
    bad["ros_missing_k"] = write(out, "ros_missing_k.yaml", text[:start] + text[end:])

    json.dump({"cases": cases, "bad": bad}, sys.stdout)


if __name__ == "__main__":
    main()

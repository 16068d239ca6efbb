"""OpenCV's centres of a symmetric circle grid, for tests/real_circle_grid.rs.

Usage: circle_grid_opencv.py COLS ROWS SPACING_MM IMAGE...

Runs cv2.findCirclesGrid (symmetric grid, OpenCV's default SimpleBlobDetector) on each 8-bit
grayscale image. The grid finder returns the blob detector's keypoint centres; each is given
with the radius of its keypoint (half its size), so that the Rust side orders them with the same
code as deckwatch's centres (the larger origin disc).

Prints JSON: {"opencv": version, "images": [{"file", "found", "centres": [[u, v, r], ...]}],
"calibration": {"rms_px", "fx", "fy", "cx", "cy", "dist"}} where the calibration is
cv2.calibrateCamera's (k1, k2, p1, p2; k3 fixed; OpenCV's own ordering) over the images where
the grid was found, a check of the Rust side's calibration.
"""

import json
import sys

import cv2
import numpy as np


def main():
    cols, rows, spacing = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    detector = cv2.SimpleBlobDetector_create()
    images, object_points, image_points, size = [], [], [], None
    grid = np.array([[i * spacing, j * spacing, 0.0] for j in range(rows) for i in range(cols)], np.float32)
    for path in sys.argv[4:]:
        gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        size = gray.shape[::-1]
        found, centres = cv2.findCirclesGrid(gray, (cols, rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID,
                                             blobDetector=detector)
        entry = {"file": path, "found": bool(found), "centres": []}
        if found:
            keypoints = detector.detect(gray)
            kp = np.array([k.pt for k in keypoints])
            for u, v in centres.reshape(-1, 2):
                nearest = int(np.argmin(np.hypot(kp[:, 0] - u, kp[:, 1] - v)))
                entry["centres"].append([float(u), float(v), float(keypoints[nearest].size / 2.0)])
            object_points.append(grid)
            image_points.append(centres.reshape(-1, 1, 2).astype(np.float32))
        images.append(entry)
    calibration = None
    if len(image_points) >= 3:
        rms, k, dist, _, _ = cv2.calibrateCamera(object_points, image_points, size, None, None,
                                                 flags=cv2.CALIB_FIX_K3)
        calibration = {"rms_px": rms, "fx": k[0, 0], "fy": k[1, 1], "cx": k[0, 2], "cy": k[1, 2],
                       "dist": dist.ravel()[:4].tolist()}
    print(json.dumps({"opencv": cv2.__version__, "images": images, "calibration": calibration}))


if __name__ == "__main__":
    main()

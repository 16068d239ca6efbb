"""Conventional baseline for the detector benchmark: OpenCV threshold + connectedComponentsWithStats
+ moments on the same frames. Prints per-frame timing percentiles (ms) as JSON.

Usage: python3 opencv_baseline.py DIR WIDTH HEIGHT THRESHOLD REPEATS
DIR holds frame_*.raw files (8-bit, tightly packed). Needs opencv-python-headless and numpy.
"""
import glob
import json
import sys
import time

import cv2
import numpy as np

cv2.setNumThreads(1)  # one core, like the detector


def detect(img, threshold):
    _, binary = cv2.threshold(img, threshold, 255, cv2.THRESH_BINARY)
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(binary, connectivity=4)
    out = []
    for i in range(1, n):
        x, y, w, h, area = stats[i]
        if area < 20 or area > 20000:
            continue
        # Intensity moments over the component's box, as a subpixel centre.
        roi = img[y : y + h, x : x + w]
        m = cv2.moments(roi, binaryImage=False)
        if m["m00"] > 0:
            out.append((x + m["m10"] / m["m00"], y + m["m01"] / m["m00"], area))
    return out


def main():
    d, w, h, t, repeats = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
    frames = [np.fromfile(f, dtype=np.uint8).reshape(h, w) for f in sorted(glob.glob(d + "/frame_*.raw"))]
    times = []
    found = 0
    for _ in range(repeats):
        for img in frames:
            t0 = time.perf_counter()
            found = len(detect(img, t))
            times.append((time.perf_counter() - t0) * 1e3)
    times.sort()
    pick = lambda p: times[min(len(times) - 1, int(p * len(times)))]
    print(json.dumps({"opencv": cv2.__version__, "n": len(times), "p50_ms": pick(0.5), "p90_ms": pick(0.9),
                      "p99_ms": pick(0.99), "blobs_last_frame": found}))


if __name__ == "__main__":
    main()

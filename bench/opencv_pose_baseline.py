"""An accuracy baseline nobody here wrote the algorithm of: OpenCV finds the marker discs
(a threshold halfway between the frame's median and its 99.99th percentile, connected
components, round ones only, background-subtracted intensity moments), the markers are
identified geometrically (bow = largest blob, centre = nearest the others' mean, ring by angle),
and cv2.solvePnP with SOLVEPNP_IPPE gives the deck's pose; the disc-centroid bias (the centre of an
imaged disc is not the image of its centre) is removed by projecting each disc's rim with the
pose, taking the centre of the ellipse OpenCV fits to it, and solving again (twice). No rolling
shutter correction. The deck's attitude follows deckwatch's conventions (docs/CONVENTIONS.md): camera from
world R_CW0 R_V^T, R = Rx(roll) Ry(pitch) Rz(yaw).

Usage: python3 opencv_pose_baseline.py RECORDING... [--csv FILE]
Prints one JSON line per recording: frames, estimated, missed (a deck in view, no pose),
false (a pose without a deck), RMSE and max error of roll, pitch, yaw (deg), cost (ms). Needs
opencv-python-headless and numpy (ci/peers.sh installs them).
"""
import csv
import json
import math
import os
import sys
import time

import cv2
import numpy as np

cv2.setNumThreads(1)

R_CW0 = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def rot(axis, a):
    c, s = math.cos(a), math.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rpy_matrix(roll, pitch, yaw):
    return rot("x", roll) @ rot("y", pitch) @ rot("z", yaw)


def rpy_of(r):
    return (
        math.atan2(-r[1, 2], r[2, 2]),
        math.asin(max(-1.0, min(1.0, r[0, 2]))),
        math.atan2(-r[0, 1], r[0, 0]),
    )


def blobs(img, min_area, max_area):
    """Disc centres (x, y) and areas: a threshold halfway between the median and the 99.99th
    percentile (bright markers on a darker deck or sea), round components, intensity moments over
    each component's box grown by 3 px with the box border's median subtracted."""
    sample = img[::4, ::4]
    threshold = 0.5 * (float(np.median(sample)) + float(np.percentile(sample, 99.99)))
    _, binary = cv2.threshold(img, threshold, 255, cv2.THRESH_BINARY)
    n, _, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    out = []
    h, w = img.shape
    for i in range(1, n):
        x, y, bw, bh, area = stats[i]
        if not (min_area <= area <= max_area):
            continue
        # Round: a disc fills pi/4 of its box whatever its tilt's direction (an ellipse's box
        # too); glints' streaks and the deck's edge do not.
        if not (0.6 <= area / float(bw * bh) <= 0.9):
            continue
        x0, y0, x1, y1 = max(0, x - 3), max(0, y - 3), min(w, x + bw + 3), min(h, y + bh + 3)
        if x0 == 0 or y0 == 0 or x1 == w or y1 == h:
            continue  # cut by the image border
        roi = img[y0:y1, x0:x1].astype(np.float64)
        border = np.concatenate([roi[0, :], roi[-1, :], roi[:, 0], roi[:, -1]])
        weights = np.clip(roi - np.median(border), 0, None)
        m = cv2.moments(weights.astype(np.float32), binaryImage=False)
        if m["m00"] > 0:
            out.append((x0 + m["m10"] / m["m00"], y0 + m["m01"] / m["m00"], float(area)))
    return out


def identify(found, n_ring):
    """Marker index -> blob, for a complete pattern only."""
    if len(found) != n_ring + 1:
        return None
    bow = max(range(len(found)), key=lambda i: found[i][2])
    rest = [i for i in range(len(found)) if i != bow]
    mean = np.mean([found[i][:2] for i in range(len(found))], axis=0)
    centre = min(rest, key=lambda i: np.hypot(*(np.array(found[i][:2]) - mean)))
    cx, cy = found[centre][:2]
    angle = lambda i: math.atan2(-(found[i][0] - cx), -(found[i][1] - cy))
    ids = {0: centre, 1: bow}
    spacing = 2 * math.pi / n_ring
    for i in rest:
        if i == centre:
            continue
        slot = round(((angle(i) - angle(bow)) % (2 * math.pi)) / spacing) % n_ring
        if slot == 0 or (1 + slot) in ids:
            return None
        ids[1 + slot] = i
    return ids


def disc_centre_bias(rvec, tvec, k, dist, centre, radius):
    """Where the imaged disc's centre lies minus where the disc's centre images."""
    a = np.linspace(0, 2 * np.pi, 64, endpoint=False)
    rim = np.stack([centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a), np.zeros_like(a)], axis=1)
    rim_px, _ = cv2.projectPoints(rim, rvec, tvec, k, dist)
    (ex, ey), _, _ = cv2.fitEllipse(rim_px.reshape(-1, 2).astype(np.float32))
    c_px, _ = cv2.projectPoints(np.array([centre], dtype=np.float64), rvec, tvec, k, dist)
    return np.array([ex, ey]) - c_px.reshape(2)


def pose(found, ids, deck, k, dist):
    obj = np.array([deck["markers_deck_xyz_m"][m] for m in sorted(ids)], dtype=np.float64)
    img = np.array([found[ids[m]][:2] for m in sorted(ids)], dtype=np.float64)
    radii = [deck["bow_marker_radius_m"] if m == 1 else deck["marker_radius_m"] for m in sorted(ids)]
    ok, rvec, tvec = cv2.solvePnP(obj, img, k, dist, flags=cv2.SOLVEPNP_IPPE)
    if not ok:
        return None
    for _ in range(2):
        corrected = np.array(
            [img[j] - disc_centre_bias(rvec, tvec, k, dist, obj[j], radii[j]) for j in range(len(obj))]
        )
        ok, rvec, tvec = cv2.solvePnP(obj, corrected, k, dist, flags=cv2.SOLVEPNP_IPPE)
        if not ok:
            return None
    return rvec


def evaluate(folder, writer):
    cam = json.load(open(os.path.join(folder, "camera.json")))
    deck = cam["deck"]
    k = np.array([[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1]], dtype=np.float64)
    dist = np.array(cam["distortion"], dtype=np.float64)
    f = min(cam["fx"], cam["fy"])
    # Discs from 0.8 m to 25 m away, as deckwatch's detector assumes.
    min_area = max(4.0, 0.5 * math.pi * (f * deck["marker_radius_m"] / 25.0) ** 2)
    max_area = 2.0 * math.pi * (f * deck["bow_marker_radius_m"] / 0.8) ** 2
    name = os.path.basename(os.path.normpath(folder))
    stats = {"recording": name, "frames": 0, "estimated": 0, "missed": 0, "false": 0}
    errors, costs = [], []
    for row in csv.DictReader(open(os.path.join(folder, "frames.csv"))):
        stats["frames"] += 1
        img = cv2.imread(os.path.join(folder, row["file"]), cv2.IMREAD_GRAYSCALE)
        t0 = time.perf_counter()
        found = blobs(img, min_area, max_area)
        ids = identify(found, deck["n_ring"])
        rvec = pose(found, ids, deck, k, dist) if ids else None
        costs.append((time.perf_counter() - t0) * 1e3)
        truth = [row.get(c, "nan") for c in ("roll_deg", "pitch_deg", "yaw_deg")]
        has_deck = all(v not in ("", "nan", "NaN") for v in truth)
        vehicle = [row.get(c) for c in ("vehicle_roll_deg", "vehicle_pitch_deg", "vehicle_yaw_deg")]
        r_v = rpy_matrix(*[math.radians(float(v)) for v in vehicle]) if all(vehicle) else np.eye(3)
        err = [math.nan] * 3
        if rvec is not None:
            stats["estimated"] += 1
            r_cd, _ = cv2.Rodrigues(rvec)
            r = r_v @ R_CW0.T @ r_cd
            est = [math.degrees(a) for a in rpy_of(r)]
            if has_deck:
                err = [e - float(t) for e, t in zip(est, truth)]
                err[2] = (err[2] + 180.0) % 360.0 - 180.0
                errors.append(err)
            else:
                stats["false"] += 1
        elif has_deck:
            stats["missed"] += 1
        if writer:
            writer.writerow([name, row["index"], int(rvec is not None)] + [f"{e:.6f}" for e in err])
    e = np.abs(np.array(errors)) if errors else np.zeros((0, 3))
    stats["rmse_deg"] = [float(np.sqrt(np.mean(e[:, i] ** 2))) if len(e) else None for i in range(3)]
    stats["max_deg"] = [float(e[:, i].max()) if len(e) else None for i in range(3)]
    stats["cost_ms_p50"] = float(np.median(costs)) if costs else None
    stats["opencv"] = cv2.__version__
    return stats


def main():
    args = sys.argv[1:]
    writer = None
    if "--csv" in args:
        i = args.index("--csv")
        writer = csv.writer(open(args[i + 1], "w", newline=""))
        writer.writerow(["recording", "index", "valid", "err_roll_deg", "err_pitch_deg", "err_yaw_deg"])
        del args[i : i + 2]
    for folder in args:
        print(json.dumps(evaluate(folder, writer)))


if __name__ == "__main__":
    main()

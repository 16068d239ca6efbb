"""Accuracy under real camera effects (issue 19): records one simulated flight per condition,
runs `deckwatch eval` and the OpenCV baseline (bench/opencv_pose_baseline.py) on the same frames,
and prints a markdown table per condition and altitude band: RMSE and max error of roll, pitch,
yaw (deg), frames missed (a deck in view, no attitude), false decks (an attitude without one) and
the estimator's cost.

Usage: python3 bench/camera_effects.py DECKWATCH_BINARY OUT_DIR [--quick]
(`--quick`: fewer frames.) Needs numpy and opencv-python-headless (ci/peers.sh installs them).
"""
import csv
import math
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
import opencv_pose_baseline  # noqa: E402

SHIP = ["--scenario", "ship", "--rate", "10"]
VGA = ["--width", "640", "--height", "480"]
# (name, frames, simulator options)
CONDITIONS = [
    ("day 640x480", 100, SHIP + VGA + ["--exposure-ms", "4"]),
    ("day 3280x2464", 100, SHIP + ["--exposure-ms", "4"]),
    ("hard 640x480 (contrast 0.35, 20 ms blur, glints)", 100,
     SHIP + VGA + ["--contrast", "0.35", "--exposure-ms", "20", "--glints", "3"]),
    ("sway, global shutter, 3280x2464", 100, SHIP + ["--vehicle", "sway"]),
    ("sway, rolling shutter 25 ms, 3280x2464", 100, SHIP + ["--vehicle", "sway", "--readout-ms", "25"]),
    ("sway, rolling shutter 12 ms, 1640x1232", 100,
     SHIP + ["--vehicle", "sway", "--readout-ms", "12", "--width", "1640", "--height", "1232"]),
    ("night 640x480", 100, SHIP + VGA + ["--look", "night", "--exposure-ms", "4"]),
    ("night 3280x2464", 100, SHIP + ["--look", "night", "--exposure-ms", "4"]),
    ("wide 120 deg 2304x1296", 100, SHIP + ["--camera", "rpi-v3-wide", "--width", "2304", "--height", "1296"]),
    ("wide 120 deg 2304x1296, calibration error 1", 100,
     SHIP + ["--camera", "rpi-v3-wide", "--width", "2304", "--height", "1296", "--calibration-error", "1"]),
    ("approach 20 -> 1 m, 3280x2464", 600, ["--scenario", "approach", "--rate", "10"]),
    ("approach 20 -> 1 m, night, 3280x2464", 600, ["--scenario", "approach", "--rate", "10", "--look", "night"]),
    ("no deck (sea, 6 glints), 3280x2464", 50, ["--scenario", "nodeck", "--rate", "10", "--glints", "6"]),
]
BANDS = [(10.0, 25.0), (5.0, 10.0), (2.0, 5.0), (1.0, 2.0)]


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def summary(rows):
    """rows: (valid, has_deck, errors or None, cost_us)."""
    errs = [r[2] for r in rows if r[0] and r[1]]
    missed = sum(1 for r in rows if r[1] and not r[0])
    false = sum(1 for r in rows if r[0] and not r[1])
    costs = sorted(r[3] for r in rows if r[3] is not None)
    if errs:
        rmse = [math.sqrt(sum(e[i] ** 2 for e in errs) / len(errs)) for i in range(3)]
        mx = [max(abs(e[i]) for e in errs) for i in range(3)]
        acc = "{:.4f} {:.4f} {:.4f} | {:.3f} {:.3f} {:.3f}".format(*rmse, *mx)
    else:
        acc = "- | -"
    cost = f"{costs[len(costs) // 2]:.0f}" if costs else "-"
    return f"{len(rows)} | {acc} | {missed} | {false} | {cost}"


def main():
    binary, out = sys.argv[1], sys.argv[2]
    quick = "--quick" in sys.argv
    os.makedirs(out, exist_ok=True)
    print("| condition | altitude | estimator | frames | RMSE roll pitch yaw (deg) | max (deg) | missed | false decks | cost p50 (us) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for k, (name, frames, options) in enumerate(CONDITIONS):
        frames = max(20, frames // 5) if quick else frames
        rec = os.path.join(out, f"c{k}")
        if not os.path.exists(os.path.join(rec, "frames.csv")):
            run([binary, "sim", "record", *options, "--frames", str(frames), "--seed", str(11 + k), "--out", rec])
        truth = {r["index"]: r for r in csv.DictReader(open(os.path.join(rec, "frames.csv")))}
        has_deck = lambda i: truth[i]["roll_deg"] not in ("", "nan", "NaN")
        alt = lambda i: float(truth[i]["alt_m"])
        eval_csv = os.path.join(out, f"c{k}-eval.csv")
        run([binary, "eval", rec, "--csv", eval_csv])
        per_estimator = {}
        for r in csv.DictReader(open(eval_csv)):
            valid = r["valid"] == "1"
            err = [float(r[c]) for c in ("err_roll_deg", "err_pitch_deg", "err_yaw_deg")] if valid else None
            per_estimator.setdefault(r["estimator"], []).append(
                (r["index"], valid, has_deck(r["index"]), err, float(r["cost_us"]))
            )
        base_csv = os.path.join(out, f"c{k}-opencv.csv")
        with open(base_csv, "w", newline="") as f:
            w = csv.writer(f)
            stats = opencv_pose_baseline.evaluate(rec, w)
        base = []
        for r in csv.DictReader(open(base_csv), fieldnames=["recording", "index", "valid", "r", "p", "y"]):
            valid = r["valid"] == "1"
            err = [float(r[c]) for c in ("r", "p", "y")] if valid and has_deck(r["index"]) else None
            base.append((r["index"], valid, has_deck(r["index"]), err, stats["cost_ms_p50"] * 1e3))
        per_estimator["opencv-ippe"] = base
        bands = BANDS if "approach" in name else [None]
        for band in bands:
            label = "5 m" if band is None else f"{band[0]:g}-{band[1]:g} m"
            if "nodeck" in options or "no deck" in name:
                label = "-"
            for est in ("full-pose", "full-pose-gs", "paper-atan2", "opencv-ippe"):
                rows = per_estimator.get(est)
                if not rows:
                    continue
                rows = [(v, d, e, c) for (i, v, d, e, c) in rows if band is None or band[0] <= alt(i) < band[1]]
                cost = [(v, d, e, None if est == "opencv-ippe" else c) for (v, d, e, c) in rows]
                if est == "opencv-ippe":
                    cost = [(v, d, e, stats["cost_ms_p50"] * 1e3) for (v, d, e, _) in rows]
                print(f"| {name} | {label} | {est} | {summary(cost)} |")
        sys.stdout.flush()


if __name__ == "__main__":
    main()

"""The descent of issue 35, judged by height (20 m down to 1 m in 60 s over the `lulls` sea,
`deckwatch sim record --scenario approach`): every frame through `deckwatch eval` (each frame
alone, as the pipeline estimates it) and the OpenCV baseline (bench/opencv_pose_baseline.py) on
the same frames. Prints one markdown row per band of height: frames, the full pose's RMSE roll /
pitch, its largest roll or pitch error, how many frames are off by more than 0.5 deg, the median
stated standard deviation, the share of errors within two of them, and OpenCV's frames, RMSE and
frames beyond 0.5 deg. Frames without an attitude are counted on the first line.

Far from the deck a nearly level ring's tilt changes its image only through perspective, about
(ring radius / height) of its size per radian: the stated deviation says how well one frame
resolves it, and the table shows whether the errors follow it.

Usage: python3 bench/descent_accuracy.py DECKWATCH_BINARY OUT_DIR [--seed S] [--rate 2]
           [--width 1640 --height 1232]
Needs numpy and opencv-python-headless (ci/peers.sh installs them).
"""
import argparse
import csv
import math
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(__file__))
import opencv_pose_baseline  # noqa: E402

BANDS_M = [(10.0, 21.0), (5.0, 10.0), (3.0, 5.0), (0.0, 3.0)]
LIMIT_DEG = 0.5


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("out")
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--rate", type=float, default=2.0)
    ap.add_argument("--width", type=int, default=1640)
    ap.add_argument("--height", type=int, default=1232)
    a = ap.parse_args()
    frames = int(round(60.0 * a.rate))
    rec = os.path.join(a.out, f"descent-{a.width}-{a.rate:g}hz-{a.seed}")
    if not os.path.exists(os.path.join(rec, "frames.csv")):
        subprocess.run(
            [a.binary, "sim", "record", "--scenario", "approach", "--frames", str(frames), "--rate", str(a.rate),
             "--width", str(a.width), "--height", str(a.height), "--seed", str(a.seed), "--out", rec],
            check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    height_m = {r["index"]: float(r["alt_m"]) for r in csv.DictReader(open(os.path.join(rec, "frames.csv")))}
    eval_csv = rec + "-eval.csv"
    subprocess.run([a.binary, "eval", rec, "--csv", eval_csv], check=True, stdout=subprocess.DEVNULL)
    ours = [r for r in csv.DictReader(open(eval_csv)) if r["estimator"] == "full-pose"]
    missed = sum(r["valid"] != "1" for r in ours)
    ours = [r for r in ours if r["valid"] == "1"]
    base_csv = rec + "-opencv.csv"
    with open(base_csv, "w", newline="") as f:
        opencv_pose_baseline.evaluate(rec, csv.writer(f))
    theirs = {}
    for r in csv.DictReader(open(base_csv), fieldnames=["recording", "index", "valid", "r", "p", "y"]):
        if r["valid"] == "1":
            theirs[r["index"]] = (float(r["r"]), float(r["p"]))
    print(f"{a.width}x{a.height}, {a.rate:g} frames a second, seed {a.seed}: {len(ours) + missed} frames, "
          f"{missed} without an attitude (OpenCV: {len(height_m) - len(theirs)})")
    print(f"| height | frames | RMSE roll / pitch (deg) | largest | beyond {LIMIT_DEG} deg | median stated std r / p "
          f"| within 2 std r / p | OpenCV frames | OpenCV RMSE r / p | OpenCV beyond {LIMIT_DEG} deg |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for lo, hi in BANDS_M:
        rows = [r for r in ours if lo <= height_m[r["index"]] < hi]
        if not rows:
            continue
        n = len(rows)
        err = [(float(r["err_roll_deg"]), float(r["err_pitch_deg"])) for r in rows]
        std = [(float(r["std_roll_deg"]), float(r["std_pitch_deg"])) for r in rows]
        worst = [max(abs(e[0]), abs(e[1])) for e in err]
        rmse = [math.sqrt(sum(e[i] ** 2 for e in err) / n) for i in range(2)]
        median = [sorted(s[i] for s in std)[n // 2] for i in range(2)]
        within = [100.0 * sum(abs(e[i]) <= 2.0 * s[i] for e, s in zip(err, std)) / n for i in range(2)]
        base = [theirs[r["index"]] for r in rows if r["index"] in theirs]
        base_rmse = [math.sqrt(sum(e[i] ** 2 for e in base) / len(base)) if base else float("nan") for i in range(2)]
        base_beyond = sum(max(abs(e[0]), abs(e[1])) > LIMIT_DEG for e in base)
        print(f"| {lo:g}-{hi:g} m | {n} | {rmse[0]:.3f} / {rmse[1]:.3f} | {max(worst):.2f} | "
              f"{sum(w > LIMIT_DEG for w in worst)} | {median[0]:.3f} / {median[1]:.3f} | "
              f"{within[0]:.0f} / {within[1]:.0f} % | {len(base)} | {base_rmse[0]:.3f} / {base_rmse[1]:.3f} | "
              f"{base_beyond} |")


if __name__ == "__main__":
    main()

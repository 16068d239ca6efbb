"""A Seapath motion log ($PSXN,23 sentences) as a deckwatch motion file (`--motion-csv` of
`decide-eval`, `predict-eval` and `trials`; docs/recording.md, "Ship motion from a file").

Kongsberg Seapath's proprietary NMEA sentence `$PSXN,23,roll,pitch,heading,heave*CS` gives, in
its manual's terms (quoted by OpenRVDAS's contrib/devices/Seapath.yaml): roll in degrees,
positive with port side up; pitch in degrees, positive with bow up; true heading in degrees;
heave in metres, positive down. `$PSXN,20,horizontal,height,heading,roll-pitch` gives each
one's quality (0 normal, 1 reduced, 2 invalid). The conversion to deckwatch's conventions
(docs/CONVENTIONS.md §2: W x to the bow, y to port, z up; R = Rx(roll) Ry(pitch) Rz(yaw);
positive roll raises port, positive pitch lowers the bow, positive yaw turns the bow to port;
heave the deck's height, up):

- The angles are taken as Seapath's Euler angles in the aerospace order (heading, then pitch,
  then roll: R = Rz(heading) Ry(pitch) Rx(roll), body forward-starboard-down in north-east-down),
  with the heading less its mean over the log, so that W's x is the ship's mean heading (as
  deckwatch's own W, CONVENTIONS.md §6). That matrix is turned into W's axes (F R F with
  F = diag(1, -1, -1), CONVENTIONS.md §7) and deckwatch's X-Y-Z angles taken from it. For small
  angles that is roll = roll, pitch = -pitch, yaw = -(heading - mean); at a ship's angles the
  orders differ by hundredths of a degree.
- Heave: -heave (Seapath's is down). It is the heave at the point Seapath was told to report
  (its "monitoring point"; the log does not say which): taken as the deck's.
- Samples whose roll-pitch quality is 2 (invalid) are dropped; ones whose fields are empty or
  whose checksum is wrong too; each is counted.

The file must be sampled at 10 Hz or faster; a 1 Hz log is resampled by a natural cubic spline
through its samples (each channel; times from the logger's timestamps at the start of each
line, or evenly at --log-rate-hz when the lines have none). A 1 Hz log holds nothing faster than
0.5 Hz, and the spline makes up nothing: between samples the motion is the smoothest curve
through them. A gap longer than --max-gap-s is refused (the spline would invent the motion in it).

Usage: python3 bench/seapath_to_motion.py LOG [--out /tmp/sea/seapath.csv] [--rate-hz 10]
       [--no-yaw] [--max-gap-s 2.5] [--log-rate-hz 1]
Standard library only. Prints the motion's statistics: mean, standard deviation and largest
excursion from zero of roll, pitch (deg) and heave (m), and each one's dominant period (the peak
of its periodogram, smoothed over 5 bins, between 2 and 40 s).

For example, OpenRVDAS's test log of RVIB Nathaniel B. Palmer's Seapath (cruise NBP1406,
2014-08-01, 1 Hz, 9.6 min; https://github.com/OceanDataTools/openrvdas, MIT licence):
    python3 bench/seapath_to_motion.py NBP1406_seap-2014-08-01 --out /tmp/sea/seapath.csv
"""

import argparse
import datetime
import math
import os
import sys


def nmea_checksum_ok(sentence):
    """Whether `$BODY*CS` has the XOR of BODY as CS (a sentence without one passes)."""
    if "*" not in sentence:
        return True
    body, _, checksum = sentence[1:].partition("*")
    value = 0
    for ch in body:
        value ^= ord(ch)
    try:
        return value == int(checksum.strip()[:2], 16)
    except ValueError:
        return False


def parse_log(lines, log_rate_hz):
    """(time s, roll, pitch, heading, heave) per valid $PSXN,23, and counts of what was dropped."""
    samples, dropped = [], {"checksum": 0, "empty": 0, "invalid roll-pitch": 0}
    reduced = 0
    quality = 0
    index = 0
    for line in lines:
        line = line.strip()
        start = line.find("$")
        if start < 0:
            continue
        stamp, sentence = line[:start].strip(), line[start:]
        if not sentence.startswith("$PSXN,"):
            continue
        if not nmea_checksum_ok(sentence):
            dropped["checksum"] += 1
            continue
        fields = sentence.split("*")[0].split(",")
        if fields[1] == "20" and len(fields) >= 6:
            quality = int(fields[5]) if fields[5].strip().isdigit() else 2
            continue
        if fields[1] != "23" or len(fields) < 6:
            continue
        if stamp:
            when = datetime.datetime.fromisoformat(stamp.replace("Z", "+00:00")).timestamp()
        else:
            when = index / log_rate_hz
        index += 1
        if quality == 2:
            dropped["invalid roll-pitch"] += 1
            continue
        try:
            roll, pitch, heading, heave = (float(f) for f in fields[2:6])
        except ValueError:
            dropped["empty"] += 1
            continue
        reduced += quality == 1
        samples.append((when, roll, pitch, heading, heave))
    return samples, dropped, reduced


def matmul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def rx(a):
    c, s = math.cos(a), math.sin(a)
    return [[1, 0, 0], [0, c, -s], [0, s, c]]


def ry(a):
    c, s = math.cos(a), math.sin(a)
    return [[c, 0, s], [0, 1, 0], [-s, 0, c]]


def rz(a):
    c, s = math.cos(a), math.sin(a)
    return [[c, -s, 0], [s, c, 0], [0, 0, 1]]


def deckwatch_angles_deg(roll_deg, pitch_deg, heading_off_mean_deg):
    """Seapath's roll, pitch and heading (off the mean) as deckwatch's roll, pitch, yaw (deg)."""
    r_ned = matmul(rz(math.radians(heading_off_mean_deg)),
                   matmul(ry(math.radians(pitch_deg)), rx(math.radians(roll_deg))))
    f = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
    r = matmul(f, matmul(r_ned, f))
    pitch = math.asin(max(-1.0, min(1.0, r[0][2])))
    roll = math.atan2(-r[1][2], r[2][2])
    yaw = math.atan2(-r[0][1], r[0][0])
    return math.degrees(roll), math.degrees(pitch), math.degrees(yaw)


def natural_spline(xs, ys):
    """Second derivatives of the natural cubic spline through (xs, ys) (xs increasing)."""
    n = len(xs)
    m = [0.0] * n
    if n < 3:
        return m
    # Tridiagonal system for the interior second derivatives (Thomas algorithm).
    a, b, c, d = [0.0] * n, [1.0] * n, [0.0] * n, [0.0] * n
    for i in range(1, n - 1):
        h0, h1 = xs[i] - xs[i - 1], xs[i + 1] - xs[i]
        a[i], b[i], c[i] = h0 / 6.0, (h0 + h1) / 3.0, h1 / 6.0
        d[i] = (ys[i + 1] - ys[i]) / h1 - (ys[i] - ys[i - 1]) / h0
    for i in range(1, n):
        w = a[i] / b[i - 1]
        b[i] -= w * c[i - 1]
        d[i] -= w * d[i - 1]
    m[n - 1] = d[n - 1] / b[n - 1]
    for i in range(n - 2, -1, -1):
        m[i] = (d[i] - c[i] * m[i + 1]) / b[i]
    m[0] = m[n - 1] = 0.0
    return m


def spline_at(xs, ys, m, x, k):
    """The spline at x, within [xs[k], xs[k + 1]]."""
    h = xs[k + 1] - xs[k]
    u, v = (xs[k + 1] - x) / h, (x - xs[k]) / h
    return (u * ys[k] + v * ys[k + 1]
            + ((u**3 - u) * m[k] + (v**3 - v) * m[k + 1]) * h * h / 6.0)


def dominant_period_s(times, values):
    """The period (s) at the peak of the periodogram (5-bin smoothed) of an evenly resampled,
    mean-removed series, between 2 and 40 s."""
    step = (times[-1] - times[0]) / (len(times) - 1)
    mean = sum(values) / len(values)
    series = [v - mean for v in values]
    n = len(series)
    powers = []
    for j in range(1, n // 2):
        w = 2 * math.pi * j / n
        re = sum(x * math.cos(w * i) for i, x in enumerate(series))
        im = sum(x * math.sin(w * i) for i, x in enumerate(series))
        powers.append((j, re * re + im * im))
    best, best_power = None, -1.0
    for idx, (j, _) in enumerate(powers):
        period = n * step / j
        if not 2.0 <= period <= 40.0:
            continue
        window = powers[max(0, idx - 2): idx + 3]
        power = sum(p for _, p in window) / len(window)
        if power > best_power:
            best, best_power = period, power
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("log")
    parser.add_argument("--out", default="/tmp/sea/seapath.csv")
    parser.add_argument("--rate-hz", type=float, default=10.0, help="the motion file's rate (10 or more)")
    parser.add_argument("--no-yaw", action="store_true", help="leave the yaw column at 0")
    parser.add_argument("--max-gap-s", type=float, default=2.5)
    parser.add_argument("--log-rate-hz", type=float, default=1.0,
                        help="the log's rate, when its lines carry no timestamps")
    args = parser.parse_args()
    if args.rate_hz < 10.0:
        sys.exit("--rate-hz: a motion file holds 10 Hz or more")

    with open(args.log, encoding="ascii", errors="replace") as f:
        samples, dropped, reduced = parse_log(f, args.log_rate_hz)
    if len(samples) < 4:
        sys.exit(f"{args.log}: {len(samples)} usable $PSXN,23 samples (4 or more needed)")
    samples.sort()
    t0 = samples[0][0]
    times = [s[0] - t0 for s in samples]
    for a, b in zip(times, times[1:]):
        if not b > a:
            sys.exit(f"{args.log}: two samples at {a:.3f} s")
        if b - a > args.max_gap_s:
            sys.exit(f"{args.log}: {b - a:.1f} s without a sample after {a:.1f} s (--max-gap-s {args.max_gap_s})")

    # The heading unwrapped, less its circular mean: W's x is the ship's mean heading.
    headings = [samples[0][3]]
    for s in samples[1:]:
        step = (s[3] - headings[-1] + 180.0) % 360.0 - 180.0
        headings.append(headings[-1] + step)
    mean_heading = math.degrees(math.atan2(sum(math.sin(math.radians(h)) for h in headings),
                                           sum(math.cos(math.radians(h)) for h in headings)))
    offsets = [(h - mean_heading + 180.0) % 360.0 - 180.0 for h in headings]
    if not args.no_yaw and max(abs(o) for o in offsets) > 90.0:
        sys.exit(f"{args.log}: the heading strays {max(abs(o) for o in offsets):.0f} deg from its mean "
                 "(a turn): cut the log or use --no-yaw")
    channels = {"roll_deg": [], "pitch_deg": [], "yaw_deg": [], "heave_m": []}
    for s, offset in zip(samples, offsets):
        roll, pitch, yaw = deckwatch_angles_deg(s[1], s[2], 0.0 if args.no_yaw else offset)
        channels["roll_deg"].append(roll)
        channels["pitch_deg"].append(pitch)
        channels["yaw_deg"].append(yaw)
        channels["heave_m"].append(-s[4])

    second_derivatives = {name: natural_spline(times, v) for name, v in channels.items()}
    steps = int(math.floor(times[-1] * args.rate_hz + 1e-9))
    directory = os.path.dirname(args.out)
    if directory:
        os.makedirs(directory, exist_ok=True)
    order = ["roll_deg", "pitch_deg", "heave_m", "yaw_deg"]
    with open(args.out, "w") as out:
        out.write(f"# From {os.path.basename(args.log)} ($PSXN,23 of a Kongsberg Seapath) by bench/seapath_to_motion.py\n")
        out.write(f"# {len(samples)} samples over {times[-1]:.1f} s from {datetime.datetime.fromtimestamp(t0, datetime.timezone.utc).isoformat()}, "
                  f"resampled at {args.rate_hz:g} Hz by a natural cubic spline; mean heading {mean_heading % 360:.2f} deg true\n")
        out.write("# roll = Seapath roll (port up), pitch = -Seapath pitch (bow up there, bow down here), "
                  "yaw = -(heading - mean), heave = -Seapath heave (down there): X-Y-Z angles of the same rotation\n")
        out.write("time_s,roll_deg,pitch_deg,heave_m,yaw_deg\n")
        k = 0
        for i in range(steps + 1):
            t = i / args.rate_hz
            while k < len(times) - 2 and t > times[k + 1]:
                k += 1
            values = [spline_at(times, channels[n], second_derivatives[n], t, k) for n in order]
            out.write(f"{t:.6f}," + ",".join(f"{v:.6f}" for v in values) + "\n")

    print(f"{args.log}: {len(samples)} samples over {times[-1]:.1f} s "
          f"(median step {sorted(b - a for a, b in zip(times, times[1:]))[len(times) // 2 - 1]:.3f} s); "
          f"dropped {dropped}; reduced roll-pitch quality {reduced}; mean heading {mean_heading % 360:.1f} deg")
    # Statistics on the log's own samples resampled evenly at its median rate (the spline).
    n_even = len(times)
    even_t = [times[-1] * i / (n_even - 1) for i in range(n_even)]
    for name, unit in [("roll_deg", "deg"), ("pitch_deg", "deg"), ("heave_m", "m"), ("yaw_deg", "deg")]:
        v = channels[name]
        mean = sum(v) / len(v)
        sd = math.sqrt(sum((x - mean) ** 2 for x in v) / len(v))
        k, even = 0, []
        for t in even_t:
            while k < len(times) - 2 and t > times[k + 1]:
                k += 1
            even.append(spline_at(times, v, second_derivatives[name], t, k))
        period = dominant_period_s(even_t, even)
        print(f"  {name:<9} mean {mean:7.3f} {unit}, sd {sd:6.3f} {unit}, largest {max(abs(x) for x in v):6.2f} {unit}, "
              f"dominant period {period:5.1f} s")
    print(f"wrote {steps + 1} rows at {args.rate_hz:g} Hz to {args.out}")


if __name__ == "__main__":
    main()

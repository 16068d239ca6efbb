"""What any linear deck-motion forecast could clear on: an upper bound on the share of the calm
windows a decision can use, on the spectrum seas of `decide-eval --motion jonswap` (issue 33) or
on any motion file (`--motion-csv`, issue 70).

The decision clears when its forecast of roll, pitch, heave and their rates over the touchdown
keeps the deck within the capacity at the accepted risk. How often that can happen is limited by
how well the motion can be forecast at all. Both modes clear by the decider's own rule
(`decide/src/decision/risk.rs` `exceedance_risk`): per limit, the largest two-sided normal tail
over the touchdown's instants; the tilt's the least over its splits between roll and pitch;
summed over the limits; at most `--risk`. Neither waits for a warm-up, loses a frame or keeps a
stricter early risk: each may clear at every decision. Calm windows and safe touchdowns are
judged as `decide/src/eval.rs` judges them (the truth every 0.02 s; a window is a span at least a
touchdown long in which the truth stays within the capacity; it is used when a clearance whose
touchdown truly stays within the capacity falls in it).

The spectrum seas: the best linear predictor there is for the sea, the exact Gaussian
conditional of the next touchdown given the last `--lags-s` of noisy samples, from the sea's true
covariance (its spectrum: known here, learnt from the samples by deckwatch); its bands are honest
by construction, and the share it uses is what no per-channel (or, with `--joint`, multichannel)
linear forecast from that span can beat. The sea is a replica of deckwatch-sim's
`SpectrumShipMotion` (sim/src/motion.rs: the JONSWAP spectrum of 300 components over 0.5-3 times
the peak frequency, encounter frequencies at 5 m/s, roll a resonance at 11 s with damping 0.1,
pitch and heave low-passed at 6 and 8 s, the heading wandering +-25 deg over 10 min) with its own
random frequencies and phases: the same sea model, not the same seas as `decide-eval --seeds`.

A motion file (`--motion-csv`, docs/recording.md "Ship motion from a file"; bench/motion_bound_lib.py):
no covariance is known, so an ideal linear forecaster is fitted on the whole file. The file is
read as decide-eval reads it (cubic Hermite between samples, rates by central differences) and
measured at decide-eval's 10 Hz with its noise (`--noise-deg` on the angles, `--heave-noise-m`
on the height; a fixed seed, the first of `--seeds`). For each instant of the touchdown
(`--step-s` apart, 0-2 s after the decision) a least-squares regression on the newest
`--lags-s` of noisy samples on the decider's 0.2 s grid (each channel's own, or with `--joint`
all three channels') forecasts the true roll, pitch, their rates and the heave rate there; its
band is Gaussian, the residuals' standard deviation per quantity and instant. It assumes the
motion is forecast linearly from those lags with one set of coefficients for the whole file,
and that the errors are normal. The global band is the residuals' over the whole file: the fit and
the band both saw the file, so it is optimistic, and it is one band for a sea that grows and
calms. With `--local-band-s S`, each decision also gets a locally honest band: its own past
residuals over the trailing S seconds (those whose truth has come by then), at least
`--local-floor` of the global band. The bound is the larger of the two shares whose
clearances stayed safe (the local one on the development files, by a little). Both bands are honest
instant by instant, not all through a touchdown as decide-eval's `at_clearances` judges the
decider (they held 85-87 % there on the held-out files); `--all-through-coverage 0.95` also
judges each band widened per quantity, with hindsight, until it holds that share all through. The
decider's stated reserves are added (`[decide]` defaults: 0.2 deg on the angles, 0.05 m/s on the
heave rate). Decisions and arrivals start at `--start-s` (after the lags and the local span);
windows are counted from there to the last decision's touchdown, each commitment judged from its
capture plus `--latency-ms` as decide-eval's. Per file and band it reports the clearances, the
unsafe ones (whose true touchdown broke the capacity), the calm windows and those used, and the
share of arrival instants (every 10 s) with a safe clearance within `--within-s`, beside an
oracle that commits on any safe touchdown; then a summary per sea state (`ssN` in the file names).

Usage: python3 bench/predict_bound.py [--lags-s 9.6] [--joint] [--sea-states 3,4,5,6]
       [--seeds 1,2] [--headings 0,110,160] [--minutes 10] [--risk 1e-3] [--band-scale 1]
       [--noise-deg 0.05] [--heave-noise-m 0.02] [--coherence 1] [--fitted]
       [--vertical-speed-error-mps 0] [--attitude-error-deg 0]
       python3 bench/predict_bound.py --motion-csv FILE[,FILE...] [--joint] [--lags-s 19.2]
       [--local-band-s 60] [--local-floor 0.2] [--within-s 120] [--start-s 80] [--step-s 0.1]
       [--latency-ms 5] [--online-window-s 240 --start-s 330] [--json] (and --risk, --band-scale, --noise-deg, --heave-noise-m, the
       reserves: 0.05 m/s and 0.2 deg by default on files)
`--fitted`: instead of the bound, the rate forecast errors of autoregressions fitted on the noisy
samples as the decider fits them, one per channel (what the decider does) and one of the three
channels together.
Needs numpy (in the environment ci/peers.sh makes, as OpenCV's dependency). Set
OPENBLAS_NUM_THREADS=1 when running several at once: threaded BLAS on small matrices only contends.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import motion_bound_lib  # noqa: E402

TAU = 2 * math.pi
GRAVITY = 9.81
# Significant wave height (m) and peak period (s) per sea state (sim/src/motion.rs).
SEA_STATES = {3: (0.88, 7.5), 4: (1.88, 8.8), 5: (3.25, 9.7), 6: (5.0, 12.4)}
COMPONENTS = 300
# `[decide]` defaults (decide/src/decision/config.rs).
LIMITS = dict(roll=5.0, pitch=5.0, tilt=5.5, roll_rate=5.0, pitch_rate=5.0, heave_rate=0.6)
TOUCHDOWN_S = 2.0
RATE_HZ = 10.0  # decide-eval's default
HORIZON_STEP_S = 0.1
TRUTH_STEP_S = 0.02
# Decisions and calm windows from here on (s): every span of lags up to this long is measured
# by then, so every variant is judged on the same windows.
START_S = 40.0
CHANNELS = ("roll", "pitch", "heave")


class Sea:
    """One spectrum sea: each channel is m(t) X(t), X a sum of the encountered waves (amplitude,
    phase offset per channel) and m the heading's modulation (roll sin, pitch cos, heave 1)."""

    def __init__(self, sea_state, seed, heading_deg, coherence=1.0):
        rng = np.random.default_rng(seed)
        hs, tp = SEA_STATES[sea_state]
        wp = TAU / tp
        w_lo, w_hi = 0.5 * wp, 3.0 * wp
        dw = (w_hi - w_lo) / COMPONENTS
        w = w_lo + (np.arange(COMPONENTS) + rng.random(COMPONENTS)) * dw
        sigma = np.where(w <= wp, 0.07, 0.09)
        peak = np.exp(-((w - wp) ** 2) / (2 * sigma**2 * wp**2))
        energy = w**-5 * np.exp(-1.25 * (wp / w) ** 4) * 3.3**peak * dw
        a = np.sqrt(2 * energy * (hs / 4) ** 2 / energy.sum())
        k = w * w / GRAVITY
        self.heading = math.radians(heading_deg)
        we = np.maximum(np.abs(w - k * 5.0 * math.cos(self.heading)), 0.05)
        slope_deg = np.degrees(k * a)
        u = we / (TAU / 11)
        resonance = 1 / np.sqrt((1 - u * u) ** 2 + (2 * 0.1 * u) ** 2)

        def low_pass(wc):
            return 1 / np.sqrt(1 + (we / wc) ** 4)

        self.rate = we
        self.phase = TAU * rng.random(COMPONENTS)
        # The simulator's waves are long-crested: every channel answers the same waves, so they
        # are fully coherent. `coherence` < 1 gives each channel that share of its energy from
        # the shared waves and the rest from waves of its own (independent phases), as a
        # short-crested sea would: cross-covariances shrink by it, each channel's own does not.
        self.coherence = coherence
        self.own_phase = {c: TAU * rng.random(COMPONENTS) for c in CHANNELS}
        self.amp = {
            "roll": (slope_deg * resonance, 0.0),
            "pitch": (0.6 * slope_deg * low_pass(TAU / 6), 0.5),
            "heave": (a * low_pass(TAU / 8), -0.3),
        }

    def modulation(self, ch, t):
        """m(t) and dm/dt."""
        chi = self.heading + math.radians(25.0) * np.sin(TAU * t / 600.0)
        chi_dot = math.radians(25.0) * TAU / 600.0 * np.cos(TAU * t / 600.0)
        if ch == "roll":
            return np.sin(chi), np.cos(chi) * chi_dot
        if ch == "pitch":
            return np.cos(chi), -np.sin(chi) * chi_dot
        return np.ones_like(t), np.zeros_like(t)

    def truth(self, ch, t):
        """The channel and its rate at times `t`."""
        a, offset = self.amp[ch]
        x, x_dot = 0.0, 0.0
        for phase, share in ((self.phase, self.coherence), (self.own_phase[ch], 1 - self.coherence)):
            if share > 0:
                arg = np.outer(t, self.rate) + phase + offset
                x = x + math.sqrt(share) * (np.sin(arg) @ a)
                x_dot = x_dot + math.sqrt(share) * (np.cos(arg) @ (a * self.rate))
        m, m_dot = self.modulation(ch, t)
        return m * x, m_dot * x + m * x_dot

    def cross(self, d, c, tau):
        """Cov(X_d(t1), X_c(t2)) and Cov(X_d(t1), X_c'(t2)) at tau = t1 - t2 (over the phases)."""
        (ad, od), (ac, oc) = self.amp[d], self.amp[c]
        half = 0.5 * ad * ac * (1.0 if d == c else self.coherence)
        arg = np.multiply.outer(tau, self.rate) + (od - oc)
        return np.cos(arg) @ half, np.sin(arg) @ (half * self.rate)

    def variance(self, ch):
        a = self.amp[ch][0]
        return 0.5 * (a * a).sum(), 0.5 * (a * a * self.rate**2).sum()


def forecast(sea, group, t_meas, z, decisions, lags, horizons, noise):
    """For each decision time, the conditional mean and std of each channel of `group` and of its
    rate at decision + horizons, given the newest `lags` samples of every channel of `group`."""
    dt = 1 / RATE_HZ
    lag = np.arange(lags)
    block = {(d, e): sea.cross(d, e, (lag[:, None] - lag[None, :]) * dt)[0] for d in group for e in group}
    tau = (-(lags - 1 - lag) * dt)[:, None] - horizons[None, :]
    target = {(d, c): sea.cross(d, c, tau) for d in group for c in group}
    nh, n = len(horizons), len(group) * lags
    mean = {c: np.zeros((len(decisions), 2, nh)) for c in group}
    std = {c: np.zeros((len(decisions), 2, nh)) for c in group}
    for i, t in enumerate(decisions):
        k = int(round(t * RATE_HZ))
        window = slice(k - lags + 1, k + 1)
        m = {d: sea.modulation(d, t_meas[window])[0] for d in group}
        cov = np.zeros((n, n))
        for a, d in enumerate(group):
            for b, e in enumerate(group):
                cov[a * lags : (a + 1) * lags, b * lags : (b + 1) * lags] = m[d][:, None] * m[e][None, :] * block[d, e]
            cov[a * lags : (a + 1) * lags, a * lags : (a + 1) * lags] += noise[d] ** 2 * np.eye(lags)
        ts = t + horizons
        columns = []
        for c in group:
            ms, ms_dot = sea.modulation(c, ts)
            columns.append(np.vstack([m[d][:, None] * ms[None, :] * target[d, c][0] for d in group]))
            columns.append(
                np.vstack([m[d][:, None] * (ms_dot * target[d, c][0] + ms * target[d, c][1]) for d in group])
            )
        observed = np.concatenate([z[d][window] for d in group])
        # Whitened: with cov = L L', mean = (L^-1 C)' (L^-1 z), variance = prior - |L^-1 C|^2.
        solved = np.linalg.solve(np.linalg.cholesky(cov), np.hstack(columns + [observed[:, None]]))
        white = solved[:, -1]
        for j, c in enumerate(group):
            ms, ms_dot = sea.modulation(c, ts)
            var_x, var_x_dot = sea.variance(c)
            value_w, rate_w = solved[:, 2 * j * nh : (2 * j + 1) * nh], solved[:, (2 * j + 1) * nh : (2 * j + 2) * nh]
            mean[c][i, 0], mean[c][i, 1] = value_w.T @ white, rate_w.T @ white
            std[c][i, 0] = np.sqrt(np.maximum(ms * ms * var_x - (value_w**2).sum(0), 0))
            std[c][i, 1] = np.sqrt(np.maximum(ms_dot**2 * var_x + ms * ms * var_x_dot - (rate_w**2).sum(0), 0))
    return mean, std


def outside(mean, std, limit):
    """P(|N(mean, std)| > limit), as `outside_probability` in decide/src/decision/risk.rs."""
    if std <= 0:
        return 0.0 if abs(mean) <= limit else 1.0
    if abs(mean) + 9 * std <= limit:
        return 0.0
    s = std * math.sqrt(2)
    return min(1.0, 0.5 * math.erfc((limit - mean) / s) + 0.5 * math.erfc((limit + mean) / s))


def tilt_outside(roll, pitch, limit):
    """The least over 13 splits of the tilt limit between roll and pitch (decide/src/decision/risk.rs)."""
    cos_limit = math.cos(math.radians(limit))
    best = 1.0
    for i in range(13):
        a = limit * i / 12
        b = math.degrees(math.acos(max(-1.0, min(1.0, cos_limit / math.cos(math.radians(a))))))
        best = min(best, outside(*roll, a) + outside(*pitch, b))
    return best


def measured(sea_state, seed, heading, args):
    """The sea, the noise per channel, the sample times and each channel's noisy samples."""
    sea = Sea(sea_state, seed, heading, args.coherence)
    noise = {"roll": args.noise_deg, "pitch": args.noise_deg, "heave": args.heave_noise_m}
    rng = np.random.default_rng(seed + 1000)
    n = int(args.minutes * 60 * RATE_HZ)
    t_meas = np.arange(n) / RATE_HZ
    z = {c: sea.truth(c, t_meas)[0] + noise[c] * rng.standard_normal(n) for c in CHANNELS}
    return sea, noise, t_meas, z


def run(sea_state, seed, heading, args):
    sea, noise, t_meas, z = measured(sea_state, seed, heading, args)
    n = len(t_meas)
    lags = int(round(args.lags_s * RATE_HZ))
    horizons = np.arange(0, TOUCHDOWN_S + 1e-9, HORIZON_STEP_S)
    decisions = t_meas[int(START_S * RATE_HZ) : n - int(TOUCHDOWN_S * RATE_HZ) - 1]
    mean, std = {}, {}
    for group in [CHANNELS] if args.joint else [(c,) for c in CHANNELS]:
        m, s = forecast(sea, group, t_meas, z, decisions, lags, horizons, noise)
        mean.update(m)
        std.update(s)
    # The band's honesty 2 s ahead: the share of true rates inside the stated 95 % band, and
    # the heave rate's RMS error.
    held, rate_error = [], {}
    for c in CHANNELS:
        rate_error[c] = sea.truth(c, decisions + horizons[-1])[1] - mean[c][:, 1, -1]
        held.append(np.mean(np.abs(rate_error[c]) <= 1.96 * std[c][:, 1, -1]))
    heave_rate_rms = math.sqrt(np.mean(rate_error["heave"] ** 2))
    scale = args.band_scale
    clears = []
    for i, t in enumerate(decisions):
        worst = [0.0] * 6
        for j in range(len(horizons)):
            roll = (mean["roll"][i, 0, j], math.hypot(scale * std["roll"][i, 0, j], args.attitude_error_deg))
            pitch = (mean["pitch"][i, 0, j], math.hypot(scale * std["pitch"][i, 0, j], args.attitude_error_deg))
            tails = (
                outside(*roll, LIMITS["roll"]),
                outside(*pitch, LIMITS["pitch"]),
                tilt_outside(roll, pitch, LIMITS["tilt"]),
                outside(mean["roll"][i, 1, j], scale * std["roll"][i, 1, j], LIMITS["roll_rate"]),
                outside(mean["pitch"][i, 1, j], scale * std["pitch"][i, 1, j], LIMITS["pitch_rate"]),
                outside(
                    mean["heave"][i, 1, j],
                    math.hypot(scale * std["heave"][i, 1, j], args.vertical_speed_error_mps),
                    LIMITS["heave_rate"],
                ),
            )
            worst = [max(w, p) for w, p in zip(worst, tails)]
            if sum(worst) > args.risk:
                break
        if sum(worst) <= args.risk:
            clears.append(t)
    # The truth, as decide/src/eval.rs judges it.
    tt = np.arange(decisions[0], t_meas[-1], TRUTH_STEP_S)
    roll, roll_rate = sea.truth("roll", tt)
    pitch, pitch_rate = sea.truth("pitch", tt)
    heave_rate = sea.truth("heave", tt)[1]
    tilt = np.degrees(np.arccos(np.clip(np.cos(np.radians(roll)) * np.cos(np.radians(pitch)), -1, 1)))
    within = (
        (np.abs(roll) <= LIMITS["roll"])
        & (np.abs(pitch) <= LIMITS["pitch"])
        & (tilt <= LIMITS["tilt"])
        & (np.abs(roll_rate) <= LIMITS["roll_rate"])
        & (np.abs(pitch_rate) <= LIMITS["pitch_rate"])
        & (np.abs(heave_rate) <= LIMITS["heave_rate"])
    )
    windows, start = [], None
    for k in range(len(tt) + 1):
        ok = k < len(tt) and within[k]
        if ok and start is None:
            start = tt[k]
        elif not ok and start is not None:
            end = tt[min(k, len(tt) - 1)]
            if end - start >= TOUCHDOWN_S:
                windows.append((start, end))
            start = None
    used, unsafe = set(), 0
    steps = int(round(TOUCHDOWN_S / TRUTH_STEP_S))
    for tc in clears:
        k0 = int(round((tc - tt[0]) / TRUTH_STEP_S))
        if not within[k0 : k0 + steps + 1].all():
            unsafe += 1
            continue
        used.update(w for w, (a, b) in enumerate(windows) if a <= tc + 1e-9 and tc + TOUCHDOWN_S <= b + 1e-9)
    return np.array([len(clears), unsafe, len(windows), len(used)]), held, heave_rate_rms


def fit_forecast(grid, order, steps, cutoff=1e-5):
    """Least-squares autoregression of `order` (each row: every channel's `order` newest values
    and an intercept; singular values below `cutoff` of the largest left out, as AR_CUTOFF in
    decide/src/forecast/ar_numerics.rs) on `grid` (rows oldest first, one column per channel), run `steps`
    ahead from its newest row. Returns the grid values from one step before the newest on."""
    n, channels = grid.shape
    design = np.ones((n - order, channels * order + 1))
    for i in range(order):
        design[:, i * channels : (i + 1) * channels] = grid[order - 1 - i : n - 1 - i]
    coef = np.linalg.lstsq(design, grid[order:], rcond=cutoff)[0]
    history = list(grid[-order:])
    out = [grid[-2], grid[-1]]
    for _ in range(steps):
        row = np.concatenate([history[-1 - i] for i in range(order)] + [np.ones(1)])
        history.append(row @ coef)
        out.append(history[-1])
    return np.array(out)


def fitted_rate_errors(sea_state, seed, heading, args):
    """RMS of the rate forecasts of fitted models, as the decider fits them (0.2 s grid, order
    48, 120 s window, refitted every second, rates by central differences): one autoregression
    per channel, and one of all three channels together."""
    sea, _, t, samples = measured(sea_state, seed, heading, args)
    n = len(t)
    z = np.stack([samples[c] for c in CHANNELS], 1)
    dt, order, window, steps = 0.2, 48, 600, (0.4, 1.0, 2.0)
    stride = int(round(dt * RATE_HZ))
    errors = {m: {h: [] for h in steps} for m in ("per channel", "joint")}
    first = int(START_S * RATE_HZ) + stride * (window - 1)
    for k in range(first, n - int(TOUCHDOWN_S * RATE_HZ) - 1, int(RATE_HZ)):
        grid = z[k - stride * (window - 1) : k + 1 : stride]
        last = int(round(max(steps) / dt)) + 1
        forecasts = {
            "per channel": np.stack([fit_forecast(grid[:, [c]], order, last)[:, 0] for c in range(3)], 1),
            "joint": fit_forecast(grid, order, last),
        }
        for model, f in forecasts.items():
            for h in steps:
                g = int(round(h / dt))
                rate = (f[g + 2] - f[g]) / (2 * dt)  # row g + 1 is grid point g
                truth = np.array([sea.truth(c, np.array([t[k] + h]))[1][0] for c in CHANNELS])
                errors[model][h].append(rate - truth)
    for model, by_h in errors.items():
        cells = []
        for h, e in by_h.items():
            rms = np.sqrt((np.array(e) ** 2).mean(0))
            cells.append(f"{rms[0]:.3f} / {rms[1]:.3f} / {rms[2]:.3f}")
        print(f"| {sea_state}/{seed}@{heading:.0f} | {model} | " + " | ".join(cells) + " |", flush=True)


def motion_files(args):
    """The bound on each of `--motion-csv`'s files, one line per file and band variant, then a
    summary per sea state (from `ssN` in the names) and over all."""
    forecast_name = "joint" if args.joint else "per channel"
    if not args.json:
        print(
            f"{forecast_name}, {args.lags_s:g} s of lags, risk {args.risk:g}, reserves "
            f"{args.attitude_error_deg:g} deg / {args.vertical_speed_error_mps:g} m/s, noise {args.noise_deg:g} deg / "
            f"{args.heave_noise_m:g} m, decisions from {args.start_s:g} s, instants {args.step_s:g} s apart, "
            f"latency {args.latency_ms:g} ms; s: the file's time (the fit and every band)"
        )
        print(
            f"| file | forecast | band | clears | unsafe | calm windows | used | arrivals served within "
            f"{args.within_s:g} s | median wait (s) | oracle served | tail beyond 3.09 (worst quantity) | s |"
        )
        print("| --- " * 12 + "|")
    summary = {}
    keys = ("clears", "unsafe", "calm_windows", "used", "arrivals", "served", "oracle_served")

    def share(a, b):
        return f"{100 * a / max(b, 1):.1f} %"

    def cells(r):
        """The columns from clears to oracle served."""
        return (
            f"{r['clears']} | {r['unsafe']} | {r['calm_windows']} | {r['used']} ({share(r['used'], r['calm_windows'])}) "
            f"| {r['served']} of {r['arrivals']} ({share(r['served'], r['arrivals'])}) "
            f"| {'-' if r.get('median_wait_s') is None else format(r['median_wait_s'], '.1f')} "
            f"| {share(r['oracle_served'], r['arrivals'])}"
        )

    for path in args.motion_csv:
        clock = time.perf_counter()
        # The same noise on every file, whatever the order they come in.
        results = motion_bound_lib.run_file(path, args, args.joint, np.random.default_rng(args.seeds[0] + 1000))
        elapsed_s = time.perf_counter() - clock
        sea_state = motion_bound_lib.sea_state_of(path)
        for r in results:
            for group in (sea_state, "all"):
                if group is not None:
                    total = summary.setdefault((r["band"], group), dict.fromkeys(keys, 0))
                    for k in keys:
                        total[k] += r[k]
            if args.json:
                extra = dict(file=path, forecast=forecast_name, sea_state=sea_state, seconds=round(elapsed_s, 2))
                print(json.dumps(dict(r, **extra)), flush=True)
                continue
            worst, tail = max(r["tail_beyond_3_09"].items(), key=lambda kv: kv[1])
            print(
                f"| {os.path.basename(path)} | {forecast_name} | {r['band']} | {cells(r)} "
                f"| {worst} {100 * tail:.2f} % | {elapsed_s:.1f} |",
                flush=True,
            )
    for band, group in sorted(summary, key=lambda k: (k[0], k[1] == "all", 0 if k[1] == "all" else k[1])):
        t = summary[band, group]
        name = "all" if group == "all" else f"sea state {group}"
        if args.json:
            print(json.dumps(dict(t, summary=name, band=band, forecast=forecast_name)))
        else:
            print(f"| {name} | {forecast_name} | {band} | {cells(t)} | | |")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ints = lambda s: [int(v) for v in s.split(",")]  # noqa: E731
    p.add_argument(
        "--lags-s",
        type=float,
        help="span of past samples (s): 9.6 on the spectrum seas (48 x 0.2 s), 19.2 on motion files (the decider's 96 x 0.2 s)",
    )
    p.add_argument("--joint", action="store_true", help="one forecast from all three channels' lags")
    p.add_argument("--sea-states", type=ints, default=[3, 4, 5, 6])
    p.add_argument("--seeds", type=ints, default=[1, 2])
    p.add_argument("--headings", type=lambda s: [float(v) for v in s.split(",")], default=[0.0, 110.0, 160.0])
    p.add_argument("--minutes", type=float, default=10.0)
    p.add_argument("--risk", type=float, default=1e-3, help="[decide] risk_per_touchdown")
    p.add_argument("--band-scale", type=float, default=1.0, help="widen the honest band by this factor")
    p.add_argument(
        "--vertical-speed-error-mps",
        type=float,
        help="[decide] vertical_speed_error_mps: added to the heave rate's deviation in quadrature, as the decider adds it "
        "(0 on the spectrum seas, as measured there; the default 0.05 on motion files)",
    )
    p.add_argument(
        "--attitude-error-deg",
        type=float,
        help="[decide] vehicle_attitude_error_deg: added to roll's and pitch's deviations in quadrature "
        "(0 on the spectrum seas; the default 0.2 on motion files)",
    )
    p.add_argument("--noise-deg", type=float, default=0.05)
    p.add_argument("--heave-noise-m", type=float, default=0.02)
    p.add_argument(
        "--coherence",
        type=float,
        default=1.0,
        help="share of each channel's energy from waves all channels answer (the simulator: 1)",
    )
    p.add_argument(
        "--motion-csv",
        type=lambda s: s.split(","),
        default=[],
        help="motion files (decide-eval --motion-csv's format) instead of the spectrum seas: a regression fitted on each",
    )
    p.add_argument("--within-s", type=float, default=120.0, help="an arrival is served by a safe clearance this soon (s)")
    p.add_argument(
        "--local-band-s",
        type=float,
        default=0.0,
        help="motion files: also judge with each decision's band from its own trailing residuals over this span (s)",
    )
    p.add_argument("--local-floor", type=float, default=0.2, help="the local band is at least this share of the global one")
    p.add_argument(
        "--all-through-coverage",
        type=float,
        default=0.0,
        help="motion files: also judge each band widened (per quantity, with hindsight) until the truth stays inside "
        "it all through the touchdown at this share of the decisions (0.95: the standard decide-eval's at_clearances "
        "holds the decider to)",
    )
    p.add_argument(
        "--start-s", type=float, default=80.0, help="motion files: the first decision and arrival (s; after the lags and local band)"
    )
    p.add_argument(
        "--online-window-s",
        type=float,
        default=0.0,
        help="motion files: fit the regression as a decider in flight could, on the trailing span of this many seconds "
        "whose truths had come, every --online-refit-s (0: on the whole file, the bound)",
    )
    p.add_argument("--online-refit-s", type=float, default=5.0, help="motion files, --online-window-s: refit this often (s)")
    p.add_argument("--latency-ms", type=float, default=5.0, help="motion files: capture to decision, as decide-eval's")
    p.add_argument("--step-s", type=float, default=0.1, help="motion files: the touchdown's judged instants this far apart (s)")
    p.add_argument("--json", action="store_true", help="motion files: one JSON object per line")
    p.add_argument(
        "--fitted",
        action="store_true",
        help="instead: rate forecast errors of fitted autoregressions, per channel and joint",
    )
    args = p.parse_args()
    on_files = bool(args.motion_csv)
    for name, spectrum_sea, motion_file in (
        ("lags_s", 9.6, 19.2),
        ("vertical_speed_error_mps", 0.0, 0.05),
        ("attitude_error_deg", 0.0, 0.2),
    ):
        if getattr(args, name) is None:
            setattr(args, name, motion_file if on_files else spectrum_sea)
    if on_files:
        lags = args.lags_s / motion_bound_lib.LAG_STEP_S
        if round(lags) < 2 or abs(lags - round(lags)) > 1e-6:
            p.error(f"--lags-s: {args.lags_s} is not a multiple of {motion_bound_lib.LAG_STEP_S} s of at least 2")
        if not 0 < args.step_s <= motion_bound_lib.TOUCHDOWN_S or args.local_band_s < 0 or not 0 < args.local_floor <= 1:
            p.error("--step-s in (0, 2], --local-band-s not negative, --local-floor in (0, 1]")
        if args.online_window_s < 0 or args.online_refit_s <= 0:
            p.error("--online-window-s not negative, --online-refit-s positive")
        if args.fitted:
            p.error("--fitted is for the spectrum seas")
        motion_files(args)
        return
    if not 2 <= round(args.lags_s * RATE_HZ) <= START_S * RATE_HZ:
        p.error(f"--lags-s: {args.lags_s} is outside [{2 / RATE_HZ}, {START_S}] s")
    if not 0 <= args.coherence <= 1:
        p.error(f"--coherence: {args.coherence} is outside [0, 1]")
    if args.fitted:
        print("| series | model | rate RMS 0.4 s | 1 s | 2 s (roll deg/s / pitch deg/s / heave m/s) |")
        print("| --- | --- | --- | --- | --- |")
        for sea_state in args.sea_states:
            for seed in args.seeds:
                for heading in args.headings:
                    fitted_rate_errors(sea_state, seed, heading, args)
        return
    total = np.zeros(4, int)
    print("| series | clears | unsafe | calm windows | used | 95 % band held 2 s ahead (roll, pitch, heave rate) | heave rate RMS 2 s ahead (m/s) |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for sea_state in args.sea_states:
        for seed in args.seeds:
            for heading in args.headings:
                c, held, rms = run(sea_state, seed, heading, args)
                total += c
                band = " / ".join(f"{100 * h:.1f} %" for h in held)
                print(
                    f"| {sea_state}/{seed}@{heading:.0f} | {c[0]} | {c[1]} | {c[2]} | {c[3]} "
                    f"({100 * c[3] / max(c[2], 1):.1f} %) | {band} | {rms:.3f} |",
                    flush=True,
                )
    print(f"| all | {total[0]} | {total[1]} | {total[2]} | {total[3]} ({100 * total[3] / max(total[2], 1):.1f} %) | | |")


if __name__ == "__main__":
    main()

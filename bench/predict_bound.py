"""What any linear deck-motion forecast could clear on (issue 33): an upper bound on the share of
the oracle's calm windows a decision can use, for `decide-eval --motion jonswap` seas and noise.

The decision clears when its forecast of roll, pitch, heave and their rates over the touchdown
keeps the deck within the capacity at the accepted risk. How often that can happen is limited by
how well the motion can be forecast at all. This script forecasts with the best linear predictor
there is for the sea: the exact Gaussian conditional of the next touchdown given the last
`--lags-s` of noisy samples, from the sea's true covariance (its spectrum: known here, learnt
from the samples by deckwatch). Its bands are honest by construction. It clears by the decider's own rule
(`decide/src/decision/risk.rs`): per limit, the largest two-sided normal tail over the
touchdown; summed over the limits; at most `--risk`. It never waits for a warm-up, never loses a
frame and may clear at every decision. The share it uses is therefore what no per-channel (or,
with `--joint`, multichannel) linear forecast from that span can beat on these seas.

The sea is a replica of deckwatch-sim's `SpectrumShipMotion` (sim/src/motion.rs: the JONSWAP
spectrum of 300 components over 0.5-3 times the peak frequency, encounter frequencies at 5 m/s,
roll a resonance at 11 s with damping 0.1, pitch and heave low-passed at 6 and 8 s, the heading
wandering +-25 deg over 10 min) with its own random frequencies and phases: the same sea model,
not the same seas as `decide-eval --seeds`. Calm windows and safe touchdowns are judged as
`decide/src/eval.rs` judges them (truth every 0.02 s, windows at least a touchdown long).

Usage: python3 bench/predict_bound.py [--lags-s 9.6] [--joint] [--sea-states 3,4,5,6]
       [--seeds 1,2] [--headings 0,110,160] [--minutes 10] [--risk 1e-3] [--band-scale 1]
       [--noise-deg 0.05] [--heave-noise-m 0.02] [--coherence 1] [--fitted]
       [--vertical-speed-error-mps 0] [--attitude-error-deg 0]
`--fitted`: instead of the bound, the rate forecast errors of autoregressions fitted on the noisy
samples as the decider fits them, one per channel (what the decider does) and one of the three
channels together.
Needs numpy (in the environment ci/peers.sh makes, as OpenCV's dependency). Set
OPENBLAS_NUM_THREADS=1 when running several at once: threaded BLAS on small matrices only contends.
"""
import argparse
import math

import numpy as np

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


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ints = lambda s: [int(v) for v in s.split(",")]  # noqa: E731
    p.add_argument("--lags-s", type=float, default=9.6, help="span of past samples (s); the decider's: 48 x 0.2 s")
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
        default=0.0,
        help="[decide] vertical_speed_error_mps: added to the heave rate's deviation in quadrature, as the decider adds it",
    )
    p.add_argument(
        "--attitude-error-deg",
        type=float,
        default=0.0,
        help="[decide] vehicle_attitude_error_deg: added to roll's and pitch's deviations in quadrature",
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
        "--fitted",
        action="store_true",
        help="instead: rate forecast errors of fitted autoregressions, per channel and joint",
    )
    args = p.parse_args()
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

"""The bound on a motion file (issue 70, item 2), for bench/predict_bound.py `--motion-csv`: what
an ideal linear forecast could clear on one file of ship motion, judged as decide/src/eval.rs
judges the decider.

The forecaster is a direct multi-step least-squares regression fitted on the whole file: for each
instant of the touchdown (`step_s` apart, 0-2 s after the decision) the true roll, pitch and their
rates and the true heave rate there, regressed on the noisy samples of the newest `lags_s` (a
0.2 s grid, the decider's) of the channel itself (per channel) or of all three (joint), with an
intercept. Its band is Gaussian: the residuals' standard deviation per quantity and instant over
the whole file (global; optimistic, since the fit and the band both saw the whole file), or over
each decision's own trailing `local_band_s` of residuals already known then (local; floored at
`local_floor` of the global one), as a decider that measures its misses as it goes could state it.
With `online_window_s` the regression is instead refitted as it goes on the trailing span whose
targets have come (`online_fit`): the same forecaster without the hindsight of the whole file.
"""
import math
import os
import re

import numpy as np

# `[decide]` defaults (decide/src/decision/config.rs): roll, pitch, tilt (deg), roll rate, pitch
# rate (deg/s), heave rate (m/s); the order of `capacity_limits`.
LIMITS = dict(roll=5.0, pitch=5.0, tilt=5.5, roll_rate=5.0, pitch_rate=5.0, heave_rate=0.6)
TOUCHDOWN_S = 2.0
DECISION_HZ = 10.0  # decide-eval's default `--rate`
LAG_STEP_S = 0.2  # the decider's 5 Hz grid (`[decide.forecast] order` lags of it)
TRUTH_STEP_S = 0.02  # decide/src/eval.rs
RATE_STEP_S = 1e-3  # eval.rs `TrueDeckState::at`: true rates by central differences this wide
NEGLIGIBLE_Z = 9.0  # risk.rs: a tail beyond this many deviations counts as 0
TILT_SPLITS = 12  # risk.rs: the tilt limit split 0, 1/12, ..., 12/12 between roll and pitch
TAIL_Z = 3.09  # where the risk is judged: an honest normal band leaves 0.2 % beyond it
Z95 = 1.959964  # a two-sided 95 % normal band's half-width, in deviations
CHANNELS = ("roll", "pitch", "heave")
# The quantities the clearing rule judges (the heave's value is not in the capacity).
QUANTITIES = (("roll", 0), ("roll", 1), ("pitch", 0), ("pitch", 1), ("heave", 1))
_erfc = np.frompyfunc(math.erfc, 1, 1)


class MotionFile:
    """A motion file (docs/recording.md, "Ship motion from a file") as
    sim/src/motion_file.rs `RecordedShipMotion` reads it: time from the first sample, a cubic
    Hermite curve between samples whose slopes are the neighbours' finite differences, held
    beyond the ends."""

    def __init__(self, path):
        with open(path) as f:
            lines = [line.strip() for line in f]
        lines = [line for line in lines if line and not line.startswith("#")]
        header = [name.strip() for name in lines[0].split(",")]
        data = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
        column = {name: data[:, header.index(name)] for name in ("time_s", "roll_deg", "pitch_deg", "heave_m")}
        self.t_s = column["time_s"]
        self.values = {"roll": column["roll_deg"], "pitch": column["pitch_deg"], "heave": column["heave_m"]}
        if len(self.t_s) < 2 or not np.all(np.diff(self.t_s) > 0):
            raise ValueError(f"{path}: fewer than two samples, or times that do not increase")
        self.duration_s = self.t_s[-1] - self.t_s[0]
        # The slope at each sample: the neighbours' difference (one-sided at the ends).
        n = len(self.t_s)
        a, b = np.maximum(np.arange(n) - 1, 0), np.minimum(np.arange(n) + 1, n - 1)
        self.slopes = {c: (v[b] - v[a]) / (self.t_s[b] - self.t_s[a]) for c, v in self.values.items()}

    def at(self, ch, t_s):
        """The channel at `t_s` after the first sample (`RecordedShipMotion::at`)."""
        ts, v, m = self.t_s, self.values[ch], self.slopes[ch]
        t = np.clip(ts[0] + np.asarray(t_s, dtype=float), ts[0], ts[-1])
        i = np.clip(np.searchsorted(ts, t, side="right"), 1, len(ts) - 1) - 1
        h = ts[i + 1] - ts[i]
        s = np.clip((t - ts[i]) / h, 0.0, 1.0)
        s2, s3 = s * s, s * s * s
        return (
            (2 * s3 - 3 * s2 + 1) * v[i]
            + (s3 - 2 * s2 + s) * h * m[i]
            + (-2 * s3 + 3 * s2) * v[i + 1]
            + (s3 - s2) * h * m[i + 1]
        )

    def rate(self, ch, t_s):
        """The channel's rate at `t_s` as eval.rs takes it: central differences 1 ms either side."""
        t_s = np.asarray(t_s, dtype=float)
        return (self.at(ch, t_s + RATE_STEP_S) - self.at(ch, t_s - RATE_STEP_S)) / (2 * RATE_STEP_S)

    def within(self, t_s):
        """Whether the true deck is within the capacity at each of `t_s` (`TrueDeckState::within`)."""
        roll, pitch = self.at("roll", t_s), self.at("pitch", t_s)
        return (
            (np.abs(roll) <= LIMITS["roll"])
            & (np.abs(pitch) <= LIMITS["pitch"])
            & (tilt_deg(roll, pitch) <= LIMITS["tilt"])
            & (np.abs(self.rate("roll", t_s)) <= LIMITS["roll_rate"])
            & (np.abs(self.rate("pitch", t_s)) <= LIMITS["pitch_rate"])
            & (np.abs(self.rate("heave", t_s)) <= LIMITS["heave_rate"])
        )


def tilt_deg(roll_deg, pitch_deg):
    """The deck normal's angle from the vertical (risk.rs `tilt_deg`)."""
    c = np.cos(np.radians(roll_deg)) * np.cos(np.radians(pitch_deg))
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def outside(mean, std, limit):
    """P(|N(mean, std)| > limit) elementwise, as risk.rs `outside_probability` (0 beyond 9
    deviations; a zero deviation: whether the mean is beyond)."""
    mean, std = np.broadcast_arrays(np.asarray(mean, float), np.asarray(std, float))
    out = np.where(np.abs(mean) <= limit, 0.0, 1.0)
    need = (std > 0) & (np.abs(mean) + NEGLIGIBLE_Z * std > limit)
    out[std > 0] = 0.0
    if need.any():
        m, s = mean[need], std[need] * math.sqrt(2)
        tails = 0.5 * (_erfc((limit - m) / s) + _erfc((limit + m) / s)).astype(float)
        out[need] = np.minimum(tails, 1.0)
    return out


def tilt_outside(roll, pitch, limit):
    """risk.rs `tilt_outside_probability` elementwise: the least over the 13 splits of the tilt
    limit between roll and pitch of the sum of their tails; 0 where even 9 deviations out on both
    stay within it. `roll`, `pitch`: (mean, std) arrays."""
    (mr, sr), (mp, sp) = roll, pitch
    out = np.zeros(np.shape(mr))
    need = tilt_deg(np.abs(mr) + NEGLIGIBLE_Z * sr, np.abs(mp) + NEGLIGIBLE_Z * sp) > limit
    if need.any():
        cos_limit = math.cos(math.radians(limit))
        best = np.ones(int(need.sum()))
        for i in range(TILT_SPLITS + 1):
            a = limit * i / TILT_SPLITS
            b = math.degrees(math.acos(max(-1.0, min(1.0, cos_limit / math.cos(math.radians(a))))))
            best = np.minimum(best, outside(mr[need], sr[need], a) + outside(mp[need], sp[need], b))
        out[need] = best
    return out


def clears(mean, std, risk, attitude_error_deg, vertical_speed_error_mps):
    """Whether each decision clears by risk.rs `exceedance_risk`: per limit the largest tail over
    the touchdown's instants, summed over the limits, at most `risk`. `mean`, `std`: per quantity
    of `QUANTITIES`, (decisions x instants). The autopilot's errors add in quadrature, as the
    decider adds them: its attitude error to roll's and pitch's deviations, its vertical-speed
    error to the heave rate's."""
    roll = (mean["roll", 0], np.hypot(std["roll", 0], attitude_error_deg))
    pitch = (mean["pitch", 0], np.hypot(std["pitch", 0], attitude_error_deg))
    tails = [
        outside(*roll, LIMITS["roll"]),
        outside(*pitch, LIMITS["pitch"]),
        tilt_outside(roll, pitch, LIMITS["tilt"]),
        outside(mean["roll", 1], std["roll", 1], LIMITS["roll_rate"]),
        outside(mean["pitch", 1], std["pitch", 1], LIMITS["pitch_rate"]),
        outside(mean["heave", 1], np.hypot(std["heave", 1], vertical_speed_error_mps), LIMITS["heave_rate"]),
    ]
    return sum(t.max(axis=1) for t in tails) <= risk


def fit(motion, groups, args, rng):
    """The regression per channel group on the decision grid. Returns the decision times (s); the
    first and last decision the fit used (every lag measured, every target within the file); the
    instants' horizons (s); per quantity the fitted mean and the residual (decisions x instants,
    NaN outside the fit) and the residuals' degrees of freedom."""
    n = int(motion.duration_s * DECISION_HZ) + 1  # decide-eval's frames over a motion file
    t_s = np.arange(n) / DECISION_HZ
    noise = {"roll": args.noise_deg, "pitch": args.noise_deg, "heave": args.heave_noise_m}
    z = {c: motion.at(c, t_s) + noise[c] * rng.standard_normal(n) for c in CHANNELS}
    stride = int(round(LAG_STEP_S * DECISION_HZ))
    lags = int(round(args.lags_s / LAG_STEP_S))
    horizons_s = np.arange(0.0, TOUCHDOWN_S + 1e-9, args.step_s)
    if horizons_s[-1] < TOUCHDOWN_S - 1e-9:  # the touchdown's end is always judged (risk.rs)
        horizons_s = np.append(horizons_s, TOUCHDOWN_S)
    first = stride * (lags - 1)
    # Targets within the file (beyond it the motion is held, not forecast).
    last = int(math.floor((motion.duration_s - TOUCHDOWN_S) * DECISION_HZ + 1e-9))
    rows = np.arange(first, last + 1)
    target_t = t_s[rows, None] + horizons_s[None, :]
    truth = {(c, d): (motion.rate if d else motion.at)(c, target_t) for c, d in QUANTITIES}
    mean, residual, dof = {}, {}, {}
    for group in groups:
        lag_index = rows[:, None] - stride * np.arange(lags)[None, :]
        design = np.hstack([z[c][lag_index] for c in group] + [np.ones((len(rows), 1))])
        keys = [q for q in QUANTITIES if q[0] in group]
        targets = np.hstack([truth[q] for q in keys])
        online = bool(getattr(args, "online_window_s", 0))
        if online:
            fitted = online_fit(design, targets, args.online_window_s, args.online_refit_s)
        else:
            fitted = design @ np.linalg.lstsq(design, targets, rcond=None)[0]
        for j, q in enumerate(keys):
            block = fitted[:, j * len(horizons_s) : (j + 1) * len(horizons_s)]
            mean[q], residual[q] = np.full((n, len(horizons_s)), np.nan), np.full((n, len(horizons_s)), np.nan)
            mean[q][rows], residual[q][rows] = block, truth[q] - block
            # Fitted online, the residuals are out of sample: no coefficients to pay for.
            dof[q] = int(np.isfinite(block[:, 0]).sum()) if online else len(rows) - design.shape[1]
    return t_s, first, last, horizons_s, mean, residual, dof


def online_fit(design, targets, window_s, refit_s):
    """The same regression fitted as a decider could fit it in flight: every `refit_s`, on the
    rows of the trailing `window_s` whose whole touchdown had come by then (their targets known),
    and used until the next refit. Rows before the first full window stay NaN. It still regresses
    on the true targets (a decider has only noisy ones), so it stays optimistic; what the fit on
    the whole file gains over it is hindsight, not a better forecaster."""
    fitted = np.full(targets.shape, np.nan)
    window = int(round(window_s * DECISION_HZ))
    step = max(1, int(round(refit_s * DECISION_HZ)))
    known = int(math.ceil(TOUCHDOWN_S * DECISION_HZ - 1e-9))
    for b in range(window + known, len(design), step):
        train = slice(b - known - window, b - known + 1)
        # Normal equations with a whisker of ridge: the same fit as lstsq where it is well posed.
        x, y = design[train], targets[train]
        gram = x.T @ x
        gram[np.diag_indices_from(gram)] += 1e-9 * np.trace(gram) / len(gram)
        coef = np.linalg.solve(gram, x.T @ y)
        fitted[b : b + step] = design[b : b + step] @ coef
    return fitted


def bands(residual, first, last, horizons_s, dof, local_band_s, local_floor):
    """Per quantity: the global band (one deviation per instant, over the whole file) and, with
    `local_band_s`, the local one (per decision: the residuals of decisions in its trailing
    `local_band_s` whose truth at that instant has come by then; at least `local_floor` of the
    global)."""
    global_std, local_std = {}, {}
    for q, r in residual.items():
        global_std[q] = np.sqrt(np.nansum(r[first : last + 1] ** 2, axis=0) / dof[q])
        if not local_band_s:
            continue
        window = int(round(local_band_s * DECISION_HZ))
        cum = np.vstack([np.zeros((1, r.shape[1])), np.cumsum(np.nan_to_num(r**2), axis=0)])
        local = np.full(r.shape, np.nan)
        k = np.arange(first + window, r.shape[0])
        for j, h in enumerate(horizons_s):
            # Decision k knows the residuals of k' <= k - known at instant h; from k - window on.
            known = int(math.ceil(h * DECISION_HZ - 1e-9))
            lo, hi = k - window, np.minimum(k - known, last)
            count = np.maximum(hi - lo + 1, 1)
            local[k, j] = np.sqrt((cum[hi + 1, j] - cum[lo, j]) / count)
        local_std[q] = np.maximum(local, local_floor * global_std[q][None, :])
    return global_std, local_std


def calm_windows(motion, t0_s, t1_s):
    """eval.rs `calm_intervals` over [t0_s, t1_s]: the truth every 0.02 s; a window runs from a
    sample within the capacity to the next one that is not (or the end), and counts when at least
    a touchdown long. Returns (starts, ends) in s and the share of the time a commit is safe."""
    n = int((t1_s - t0_s) / TRUTH_STEP_S)
    t = t0_s + np.arange(n + 1) * TRUTH_STEP_S
    ok = np.append(motion.within(t[:n]), False)
    edges = np.diff(np.concatenate([[0], ok.astype(np.int8)]))
    start_k, end_k = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    long_enough = t[end_k] - t[start_k] >= TOUCHDOWN_S
    starts, ends = t[start_k][long_enough], t[end_k][long_enough]
    return starts, ends, (ends - starts - TOUCHDOWN_S).sum() / (t1_s - t0_s)


def safe_touchdowns(motion, commit_s):
    """Whether the truth stays within the capacity over the touchdown of a commit at each of
    `commit_s` (eval.rs `judge`: every 0.02 s from the commit to contact, both ends)."""
    steps = math.ceil(TOUCHDOWN_S / TRUTH_STEP_S)
    after_s = np.minimum(np.arange(steps + 1) * TRUTH_STEP_S, TOUCHDOWN_S)
    safe = np.empty(len(commit_s), bool)
    for a in range(0, len(commit_s), 2000):  # chunks keep the arrays small
        safe[a : a + 2000] = motion.within(commit_s[a : a + 2000, None] + after_s[None, :]).all(axis=1)
    return safe


def judge(decision_s, clear, safe, windows, args):
    """Clearances `clear` at `decision_s` (whose touchdowns are truly `safe` or not) judged as
    eval.rs judges a decide-eval series whose frames are these decisions (`windows`: the calm
    windows' starts and ends over [first frame, last frame + touchdown]); and the arrivals every
    10 s from the first decision with `within_s` of decisions after them: the share with a safe
    clearance within `within_s` (and the same for an oracle that commits on any safe touchdown)."""
    commit_s = decision_s + args.latency_ms / 1e3
    starts, ends = windows
    good = commit_s[clear & safe]
    w = np.searchsorted(starts, good + 1e-9, side="right") - 1
    inside = (w >= 0) & (good + TOUCHDOWN_S <= ends[np.maximum(w, 0)] + 1e-9)
    arrivals_s = np.arange(decision_s[0], decision_s[-1] - args.within_s + 1e-9, 10.0)

    def waits(ok):
        """Per arrival, the wait to the first decision at or after it that is `ok` (inf: none)."""
        times = decision_s[ok]
        k = np.searchsorted(times, arrivals_s - 1e-9)
        found = k < len(times)
        wait = np.full(len(arrivals_s), np.inf)
        wait[found] = times[k[found]] - arrivals_s[found]
        return wait

    wait_s, oracle_wait_s = waits(clear & safe), waits(safe)
    served = wait_s <= args.within_s + 1e-9
    return dict(
        clears=int(clear.sum()),
        unsafe=int((clear & ~safe).sum()),
        calm_windows=len(starts),
        used=len(np.unique(w[inside])),
        arrivals=len(arrivals_s),
        served=int(served.sum()),
        median_wait_s=round(float(np.median(wait_s[served])), 2) if served.any() else None,
        oracle_served=int((oracle_wait_s <= args.within_s + 1e-9).sum()),
    )


def run_file(path, args, joint, rng):
    """One motion file: per band variant (global; with `local_band_s` also local) the judged
    clearances and the band's tail (the share of residuals beyond `TAIL_Z` stated deviations)."""
    motion = MotionFile(path)
    groups = [CHANNELS] if joint else [(c,) for c in CHANNELS]
    t_s, first, last, horizons_s, mean, residual, dof = fit(motion, groups, args, rng)
    start = int(math.ceil(args.start_s * DECISION_HZ - 1e-9))
    # The last decision whose judged touchdown (from capture + latency) is within the file.
    stop = min(last, int(math.floor((motion.duration_s - TOUCHDOWN_S - args.latency_ms / 1e3) * DECISION_HZ)))
    if stop <= start:
        raise ValueError(f"{path}: {motion.duration_s:.0f} s is too short for --start-s {args.start_s}")
    # Every decision judged has all its lags and a full trailing span of residuals.
    fitted_from = first + int(round(getattr(args, "online_window_s", 0) * DECISION_HZ))
    if getattr(args, "online_window_s", 0):
        fitted_from += int(math.ceil(TOUCHDOWN_S * DECISION_HZ - 1e-9))
    if start < fitted_from + int(round((args.local_band_s or 0) * DECISION_HZ)):
        raise ValueError(
            f"--start-s {args.start_s}: before the lags, the online fit's window and the local band's span are measured"
        )
    global_std, local_std = bands(residual, first, last, horizons_s, dof, args.local_band_s, args.local_floor)
    variants = [("global", global_std)]
    if args.local_band_s:
        variants.append((f"local {args.local_band_s:g} s", local_std))
    # The truth, judged once for every variant: each decision's touchdown, the calm windows.
    window = slice(start, stop + 1)
    decision_s = t_s[window]
    safe = safe_touchdowns(motion, decision_s + args.latency_ms / 1e3)
    starts, ends, safe_time_share = calm_windows(motion, decision_s[0], decision_s[-1] + TOUCHDOWN_S)
    out = []
    m = {q: mean[q][window] for q in QUANTITIES}
    r = {q: residual[q][window] for q in QUANTITIES}
    name_of = {q: f"{q[0]}{'_rate' if q[1] else ''}" for q in QUANTITIES}

    def judged(name, s):
        clear = clears(m, s, args.risk, args.attitude_error_deg, args.vertical_speed_error_mps)
        result = judge(decision_s, clear, safe, (starts, ends), args)
        tail = {name_of[q]: float(np.mean(np.abs(r[q]) > TAIL_Z * s[q])) for q in QUANTITIES}
        # As decide-eval's `at_clearances`: over each cleared touchdown, the truth inside the
        # stated 95 % band at every instant.
        held = {name_of[q]: float(np.mean(all_through[q](s)[clear])) if clear.any() else None for q in QUANTITIES}
        return dict(
            result,
            band=name,
            safe_time_share=float(safe_time_share),
            tail_beyond_3_09=tail,
            inside_95_all_through_at_clearances=held,
        )

    # Per decision and quantity, whether the truth stayed inside the band all through the touchdown.
    all_through = {q: (lambda s, q=q: (np.abs(r[q]) <= Z95 * s[q]).all(axis=1)) for q in QUANTITIES}
    for name, std in variants:
        s = {q: args.band_scale * np.broadcast_to(std[q], mean[q].shape)[window] for q in QUANTITIES}
        out.append(judged(name, s))
        if args.all_through_coverage:
            # The same band held to the decider's standard: widened per quantity (never
            # narrowed) until the truth stays inside it all through the touchdown at this share
            # of every decision, with hindsight over the whole file (optimistic, as a bound is).
            widening = {
                q: max(1.0, float(np.quantile(np.max(np.abs(r[q]) / (Z95 * s[q]), axis=1), args.all_through_coverage)))
                for q in QUANTITIES
            }
            wide = {q: s[q] * widening[q] for q in QUANTITIES}
            result = judged(f"{name}, all through {100 * args.all_through_coverage:g} %", wide)
            result["widening"] = {name_of[q]: round(widening[q], 3) for q in QUANTITIES}
            out.append(result)
    return out


def sea_state_of(path):
    """The sea state a file's name carries (`...ssN...`), else None."""
    found = re.search(r"ss(\d+)", os.path.basename(path))
    return int(found.group(1)) if found else None

#!/usr/bin/env python3
"""Draw records from plants written apart from hystbench (benches/independent/plants.py).

    python3 benches/independent/make.py --count 60 --seed 1 --out DIR [--classes 2dof-short,...]

Writes DIR/records/NNNN.csv (t, u or u1,u2, y or y1,y2: what `hystbench identify` reads),
DIR/truth/NNNN.csv (the noiseless outputs) and DIR/index.json (per record its class, what was
drawn and the noise). Member i of seed s is the same whatever --count and --classes. Needs
numpy and scipy. `score.py DIR` runs the default identifier on every record.
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plants as P  # noqa: E402

CLASSES = {
    # name: (share, samples (lo, hi), sampling period s (lo, hi), inputs)
    "2dof-short": (0.35, (500, 500), (5e-4, 5e-3), 2),
    "1dof-short": (0.35, (1000, 5000), (2e-4, 5e-3), 1),
    "1dof-long": (0.30, (10000, 40000), (1e-4, 2e-3), 1),
}


def log_uniform(rng, lo, hi):
    return math.exp(rng.uniform(math.log(lo), math.log(hi)))


# ---------------------------------------------------------------- excitations


def excitation(rng, n, ts, cap_hz):
    """One input: (values, description). Frequencies between 4 periods per record and cap_hz."""
    t = np.arange(n) * ts
    T = n * ts
    f_lo = 4.0 / T
    f_hi = max(cap_hz, 1.5 * f_lo)
    amp = log_uniform(rng, 5.0, 100.0)
    f = log_uniform(rng, f_lo, f_hi)
    kind = rng.choice(
        ["sine", "amplitudes", "decaying", "modulated", "multisine", "staircase",
         "triangle", "random-walk", "chirp"],
        p=[0.10, 0.12, 0.12, 0.14, 0.12, 0.10, 0.10, 0.10, 0.10],
    )
    if kind == "sine":
        u = amp * np.sin(2 * math.pi * f * t + rng.uniform(0, 2 * math.pi))
    elif kind == "amplitudes":
        # 25, 50, 75, 100 % of the amplitude in turn (several periods each), shuffled
        levels = rng.permutation([0.25, 0.5, 0.75, 1.0])
        env = levels[np.minimum((4 * t / T).astype(int), 3)]
        u = amp * env * np.sin(2 * math.pi * f * t)
    elif kind == "decaying":
        tau = T * rng.uniform(0.3, 1.0)
        u = amp * np.exp(-t / tau) * np.sin(2 * math.pi * f * t)
    elif kind == "modulated":
        fm = log_uniform(rng, 1.0 / T, max(f / 4, 1.2 / T))
        u = amp * np.sin(2 * math.pi * f * t) * (0.55 + 0.45 * np.sin(2 * math.pi * fm * t))
    elif kind == "multisine":
        k = rng.integers(3, 12)
        fs_ = np.exp(np.linspace(math.log(f_lo), math.log(f_hi), k))
        ph = rng.uniform(0, 2 * math.pi, k)
        u = np.sum(np.sin(2 * math.pi * fs_[:, None] * t[None, :] + ph[:, None]), axis=0)
        u *= amp / np.max(np.abs(u))
    elif kind == "staircase":
        m = rng.integers(6, 20)
        levels = rng.uniform(-amp, amp, m)
        u = levels[np.minimum((m * t / T).astype(int), m - 1)]
    elif kind == "triangle":
        u = amp * signal_triangle(f * t)
    elif kind == "random-walk":
        # band-limited noise on a drifting offset: non-nested minor loops
        w = rng.standard_normal(n)
        a = math.exp(-2 * math.pi * f * ts)
        x = np.zeros(n)
        for i in range(1, n):
            x[i] = a * x[i - 1] + (1 - a) * w[i]
        x /= max(np.max(np.abs(x)), 1e-12)
        drift = np.sin(2 * math.pi * t / (T * rng.uniform(1.0, 3.0)) + rng.uniform(0, 6.3))
        u = amp * (0.7 * x + 0.3 * drift)
    else:
        f1 = log_uniform(rng, f_lo, f_hi)
        f0, f1 = sorted([f, f1])
        f1 = max(f1, 2 * f0)
        u = amp * np.sin(2 * math.pi * f0 * T / math.log(f1 / f0)
                         * (np.exp(t / T * math.log(f1 / f0)) - 1))
    offset = 0.0
    if rng.uniform() < 0.25:
        offset = rng.uniform(-0.6, 0.6) * amp
        u = u + offset
    return u, f"{kind} ({amp:.3g} V, {f:.3g} Hz, offset {offset:.3g} V)"


def signal_triangle(x):
    return 2 * np.abs(2 * (x - np.floor(x + 0.5))) - 1


# ---------------------------------------------------------------- hysteresis paths


def path(rng, u, ts, gain, cross=False):
    """One hysteretic path u -> w: (function of the input, description)."""
    U = max(np.max(np.abs(u)), 1e-9)
    span = 0.5 * (np.max(u) - np.min(u))
    if cross and rng.uniform() < 0.4:
        return (lambda x: gain * x), f"linear {gain:.3g}"
    kinds = ["bouc-wen", "pi", "gpi", "mpi", "poly-pi", "rate-pi"]
    p = [0.30, 0.20, 0.15, 0.15, 0.10, 0.10] if not cross else [0.5, 0.5, 0, 0, 0, 0]
    kind = rng.choice(kinds, p=p)
    share = rng.uniform(0.1, 0.6)  # of the gain that is hysteretic
    if kind == "bouc-wen":
        n = 1.0 if rng.uniform() < 0.75 else rng.uniform(1.5, 3.0)
        b = log_uniform(rng, 0.3, 8.0) / U
        g = rng.uniform(-0.8, 0.8) * b
        w = log_uniform(rng, 0.05, 0.35)
        a = (w * abs(gain) * U) ** n * (b + g)
        s = 1.0 if gain >= 0 else -1.0
        d = abs(gain)
        return (lambda x: s * P.bouc_wen(x, d, a, b, g, n)), (
            f"bouc-wen d={d:.3g} A={a:.3g} B={b:.3g} Gamma={g:.3g} n={n:.2f}")
    nplays = int(rng.integers(6, 15))
    tau = rng.uniform(0.0, 4.0) / max(span, 1e-9)
    r, wts = P.pi_density(nplays, max(span, 1e-9), 1.0, tau)
    wts[0] = 0.0
    wts *= gain * share / max(np.sum(wts), 1e-12)
    wts[0] = gain * (1 - share)
    if kind == "pi":
        return (lambda x: P.prandtl_ishlinskii(x, r, wts)), (
            f"classical PI, {nplays} plays, tau*span={tau * span:.2f}")
    if kind == "gpi":
        # tanh envelopes, ascending and descending ones apart (asymmetric, saturating)
        a1 = rng.uniform(0.4, 1.6) / U
        a1d = a1 * rng.uniform(0.7, 1.3)
        a2, a2d = rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4)

        def env(a1_, a2_):
            c = U / math.tanh(a1_ * U)
            return lambda x: c * (np.tanh(a1_ * x + a2_) - math.tanh(a2_))

        up, down = env(a1, a2), env(a1d, a2d)
        return (lambda x: P.generalised_pi(x, r, wts, up, down)), (
            f"generalised PI, {nplays} plays, envelopes tanh({a1 * U:.2f} u/U + {a2:.2f}) / "
            f"tanh({a1d * U:.2f} u/U + {a2d:.2f})")
    if kind == "mpi":
        Y = abs(gain) * U
        a, b = rng.uniform(0.2, 0.7), rng.uniform(0.2, 0.7)
        c1, c2 = rng.uniform(-0.35, 0.35), rng.uniform(-0.35, 0.35)
        d, ws = [-b * Y, 0.0, a * Y], [c1, 1.0, c2]
        s = 1.0 if gain >= 0 else -1.0
        return (lambda x: s * P.dead_zones(s * P.prandtl_ishlinskii(x, r, wts), d, ws)), (
            f"modified PI, {nplays} plays, dead zones at {d[0]:.3g}, {d[2]:.3g} weights "
            f"{c1:.2f}, {c2:.2f}")
    if kind == "poly-pi":
        q = rng.uniform(-0.15, 0.15)
        a3 = q * gain / U**2
        return (lambda x: a3 * x**3 + P.prandtl_ishlinskii(x, r, wts)), (
            f"PI with a cubic input term ({q:+.2f} of the gain at the peak)")
    # rate-dependent thresholds: up to 10-50 % of the span more at the record's top rate
    alpha = max(span, 1e-9) / nplays
    rate = np.max(np.abs(np.gradient(u, ts)))
    beta = rng.uniform(0.1, 0.5) * max(span, 1e-9) / max(rate, 1e-12)
    rho = gain * share / max(np.sum(np.exp(-tau * alpha * np.arange(1, nplays + 1)) * alpha),
                             1e-12)
    p0 = gain * (1 - share)
    return (lambda x: p0 * x + P.rate_dependent_pi(x, ts, alpha, beta, rho, tau, nplays)), (
        f"rate-dependent PI, {nplays} plays, beta*rate={beta * rate / span:.2f} span")


# ---------------------------------------------------------------- plants


def creep(rng, ts):
    """(function of (w, u), description) or None."""
    kind = rng.choice(["series", "beside", "log"], p=[0.4, 0.3, 0.3])
    if kind == "log":
        gamma, t0 = log_uniform(rng, 0.005, 0.05), log_uniform(rng, 0.01, 0.5)
        return (lambda w, u: P.log_creep(w, gamma, t0, ts)), (
            f"log creep gamma={gamma:.3g} t0={t0:.3g} s")
    k = int(rng.integers(1, 4))
    taus = sorted(log_uniform(rng, 0.02, 200.0) for _ in range(k))
    total = log_uniform(rng, 0.01, 0.2)
    g = rng.dirichlet(np.ones(k)) * total
    if kind == "series":
        return (lambda w, u: P.kelvin_voigt(w, taus, g, ts)), (
            f"Kelvin-Voigt creep on the hysteresis taus={[round(t, 3) for t in taus]} "
            f"g={[round(x, 3) for x in g]}")
    # beside: on the input, scaled by the path's small-signal gain (w/u at the peak)
    return "beside", (taus, g), (
        f"Kelvin-Voigt creep beside, on the input, taus={[round(t, 3) for t in taus]} "
        f"g={[round(x, 3) for x in g]}")


def dynamics(rng, ts):
    """(transfer functions to sum, method, description) or None for a quasi-static output."""
    if rng.uniform() < 0.3:
        return None
    method = rng.choice(["zoh", "foh", "bilinear"], p=[0.5, 0.25, 0.25])
    method = os.environ.get("IND_DISC", method)
    nyq = 0.5 / ts
    if rng.uniform() < 0.15:
        tau = log_uniform(rng, 2 * ts, 50 * ts)
        return [(1.0, P.lag(tau))], method, f"first-order lag {tau:.3g} s ({method})"
    fn = log_uniform(rng, nyq / 100, nyq / 3)
    zeta = log_uniform(rng, 0.02, 0.7)
    tfs = [(1.0, P.mode(fn, zeta))]
    desc = f"mode {fn:.4g} Hz zeta {zeta:.3f}"
    if rng.uniform() < 0.2:
        f2 = fn * rng.uniform(2.0, 5.0)
        c = rng.uniform(0.1, 0.3)
        zeta2 = log_uniform(rng, 0.02, 0.3)
        if f2 < nyq / 1.5 and not os.environ.get("IND_ONE_MODE"):
            tfs = [(1 - c, P.mode(fn, zeta)), (c, P.mode(f2, zeta2))]
            desc += f" + mode {f2:.4g} Hz ({c:.2f})"
    return tfs, method, desc + f" ({method})"


def through(x, dyn, ts):
    if dyn is None:
        return x
    tfs, method, _ = dyn
    return sum(c * P.lti(x, tf, ts, method) for c, tf in tfs)


def draw_member(seed, index, only=None):
    rng = np.random.default_rng([seed, index])
    names = list(CLASSES)
    cls = rng.choice(names, p=[CLASSES[c][0] for c in names])
    if only and cls not in only:
        return None
    _, (n_lo, n_hi), (t_lo, t_hi), m = CLASSES[cls]
    n = n_lo if n_lo == n_hi else int(round(log_uniform(rng, n_lo, n_hi)))
    ts = log_uniform(rng, t_lo, t_hi)
    dyns = [dynamics(rng, ts) for _ in range(m)]
    cap = 0.1 / ts
    for d in dyns:
        if d is not None:
            lowest = min(_tf_corner(tf) for _, tf in d[0])
            cap = min(cap, 2.0 * lowest)
    inputs = [excitation(rng, n, ts, cap) for _ in range(m)]
    u = [x for x, _ in inputs]
    desc = {"class": cls, "samples": n, "sampling_period_s": ts,
            "inputs": [d for _, d in inputs], "outputs": []}
    ys = []
    two_way = rng.uniform() < 0.6
    cross_both_modes = rng.uniform() < 0.5 and not os.environ.get("IND_OWN_MODE")
    for i in range(m):
        gain = log_uniform(rng, 0.1, 1.5) * (-1.0 if rng.uniform() < 0.15 else 1.0)
        f, pdesc = path(rng, u[i], ts, gain)
        w_direct = f(u[i])
        od = {"direct": pdesc}
        w_cross = None
        if m == 2 and (two_way or i == 1):
            j = 1 - i
            cg = gain * log_uniform(rng, 0.05, 0.3) * (-1.0 if rng.uniform() < 0.5 else 1.0)
            fc, cdesc = path(rng, u[j], ts, cg, cross=True)
            w_cross = fc(u[j])
            od["cross"] = cdesc
        cr = creep(rng, ts) if rng.uniform() < 0.5 else None
        w = w_direct + (w_cross if w_cross is not None and not cross_both_modes else 0.0)
        if cr is not None:
            if cr[0] == "beside":
                taus, g = cr[1]
                k0 = gain
                w = w + k0 * (P.kelvin_voigt(u[i], taus, g, ts) - u[i])
            else:
                w = cr[0](w, u[i])
            od["creep"] = cr[-1]
        y = through(w, dyns[i], ts)
        if w_cross is not None and cross_both_modes:
            both = [d for d in dyns if d is not None]
            if both:
                y = y + sum(through(w_cross, d, ts) for d in both) / len(both)
                od["cross_dynamics"] = "both modes"
            else:
                y = y + w_cross
        od["dynamics"] = dyns[i][2] if dyns[i] is not None else "quasi-static"
        ys.append(y)
        desc["outputs"].append(od)
    noise = []
    meas = []
    for y in ys:
        s = log_uniform(rng, 5e-4, 1e-2) * (np.max(y) - np.min(y))
        noise.append(s)
        meas.append(y + s * rng.standard_normal(n))
    desc["noise_std"] = noise
    if not all(np.all(np.isfinite(v)) for v in u + ys + meas):
        raise FloatingPointError(f"member {index} of seed {seed} is not finite")
    return desc, ts, u, ys, meas


def _tf_corner(tf):
    num, den = tf
    if len(den) == 3:
        return math.sqrt(den[2]) / (2 * math.pi)
    return 1.0 / (2 * math.pi * den[0])


def write_csv(path, ts, cols):
    names = [c for c, _ in cols]
    data = np.column_stack([np.arange(len(cols[0][1])) * ts] + [v for _, v in cols])
    with open(path + ".part", "w") as fh:
        fh.write(",".join(["t"] + names) + "\n")
        for row in data:
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    os.replace(path + ".part", path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=60)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", required=True)
    ap.add_argument("--classes", default="")
    ap.add_argument("--force", action="store_true")
    a = ap.parse_args()
    if a.count < 1:
        sys.exit("make.py: --count must be 1 or more")
    only = set(c for c in a.classes.split(",") if c)
    bad = only - set(CLASSES)
    if bad:
        sys.exit(f"make.py: unknown class {sorted(bad)}; the classes are {list(CLASSES)}")
    if os.path.exists(a.out) and not a.force:
        sys.exit(f"make.py: {a.out} exists; give --force to replace it")
    os.makedirs(os.path.join(a.out, "records"), exist_ok=True)
    os.makedirs(os.path.join(a.out, "truth"), exist_ok=True)
    index, i = [], 0
    while len(index) < a.count:
        got = draw_member(a.seed, i, only)
        if got is not None:
            desc, ts, u, ys, meas = got
            m = len(u)
            un = ["u"] if m == 1 else [f"u{k + 1}" for k in range(m)]
            yn = ["y"] if m == 1 else [f"y{k + 1}" for k in range(m)]
            name = f"{i:04d}"
            write_csv(os.path.join(a.out, "records", name + ".csv"), ts,
                      list(zip(un, u)) + list(zip(yn, meas)))
            write_csv(os.path.join(a.out, "truth", name + ".csv"), ts, list(zip(yn, ys)))
            desc["index"] = i
            index.append(desc)
            print(f"{name} {desc['class']}: {desc['samples']} samples", flush=True)
        i += 1
    with open(os.path.join(a.out, "index.json"), "w") as fh:
        json.dump({"seed": a.seed, "members": index}, fh, indent=1)


if __name__ == "__main__":
    main()

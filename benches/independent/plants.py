"""Hysteretic plants written apart from hystbench's effect library (numpy and scipy only).

Every operator here is written from the textbook equations (docs/models.md gives the same
references), not from the Rust code, and where the literature offers several forms this file
draws among them: a record made here tests whether the identifier works on a plant that its
own grey-box family was not written to hold.

- Bouc-Wen in Rakotondrabe's form, H[u] = d u - h, dh/du = A - B sgn(du) |h|^(n-1) h -
  Gamma |h|^n (Rakotondrabe 2011; Ismail, Ikhouane & Rodellar 2009), integrated in u by RK4
  substeps;
- classical Prandtl-Ishlinskii with the density p(r) = rho exp(-tau r) (Al Janaideh et al.)
  on thresholds (i - 1)/n (u_max - u_min)/2;
- generalised Prandtl-Ishlinskii with tanh envelopes, different on the ascending and the
  descending edge (Al Janaideh, Rakheja & Su 2011): asymmetric, saturating loops;
- modified Prandtl-Ishlinskii (Kuhnen 2003): the PI output through one-sided dead zones;
- a polynomial input term beside the PI (Gu, Zhu & Su 2014);
- rate-dependent PI, thresholds r_j + beta |du/dt| (Al Janaideh, Su & Rakheja 2008);
- creep as a Kelvin-Voigt chain on the hysteresis output, as the same chain on the input
  beside it (Rakotondrabe, Clevy & Lutz 2010), or as the logarithmic law of the PI tutorial
  (step response 1 + gamma log10(1 + t / t0)), by FFT convolution;
- linear dynamics: a second-order mode (optionally a second mode), or a first-order lag,
  discretised by zero-order hold, first-order hold or Tustin (scipy.signal.cont2discrete);
- 2-DoF: y_i = sum_j D_ij[...H_ij[u_j]] with cross paths through the own mode or through
  both modes, D_ij = (D_i + D_j) / 2 (PHYSICS: cross terms share the modes).
"""

import math

import numpy as np
from scipy import signal


# ---------------------------------------------------------------- hysteresis operators


def bouc_wen(u, d, a, b, g, n=1.0, substeps=16):
    """Rakotondrabe's form d u - h; h from dh/du integrated by RK4 in u (rate-independent),
    in substeps short against the loop's stiffness (|h| is bounded by (A/(B+Gamma))^(1/n))."""
    h = 0.0
    out = np.empty(len(u))
    prev = 0.0  # the operator starts relaxed at u = 0
    bound = (abs(a) / max(b + g, 1e-300)) ** (1.0 / n)
    stiff = (b + abs(g)) * n * bound ** (n - 1.0)
    for k, v in enumerate(u):
        m = max(substeps, int(math.ceil(abs(v - prev) * stiff / 0.1)))
        du = (v - prev) / m
        s = 1.0 if du >= 0 else -1.0

        def f(hh):
            ah = abs(hh)
            return a - b * s * (ah ** (n - 1.0)) * hh - g * ah**n

        for _ in range(m):
            if du == 0.0:
                break
            k1 = f(h)
            k2 = f(h + 0.5 * du * k1)
            k3 = f(h + 0.5 * du * k2)
            k4 = f(h + du * k3)
            h += du * (k1 + 2 * k2 + 2 * k3 + k4) / 6.0
        prev = v
        out[k] = d * v - h
    return out


def plays(u, thresholds, lo=None, hi=None):
    """Play operators z_r(k) = max(lo(k) - r, min(hi(k) + r, z_r(k-1))), relaxed at 0.

    `lo` and `hi` are the ascending and descending envelopes' values (the input itself for
    a classical play). Returns an array (len(u), len(thresholds)).
    """
    lo = u if lo is None else lo
    hi = u if hi is None else hi
    r = np.asarray(thresholds, dtype=float)
    z = np.zeros(len(r))
    out = np.empty((len(u), len(r)))
    for k in range(len(u)):
        z = np.maximum(lo[k] - r, np.minimum(hi[k] + r, z))
        out[k] = z
    return out


def pi_density(n, span, rho, tau):
    """Thresholds (i - 1)/n * span, i = 1..n (the first is 0: the linear term), and the
    weights of the density rho exp(-tau r) times the threshold spacing (the first: p0)."""
    r = np.arange(n) * span / n
    w = rho * np.exp(-tau * r) * (span / n)
    return r, w


def prandtl_ishlinskii(u, r, w):
    return plays(u, r) @ w


def generalised_pi(u, r, w, env_up, env_down):
    """Al Janaideh's generalised play: ascending edge on env_up(u), descending on env_down(u)."""
    gl, gr = env_up(u), env_down(u)
    z = plays(u, r, gl, gr)
    return z @ w


def dead_zones(y, d, ws):
    """Kuhnen's superposition of one-sided dead zones S_d(y) (d > 0: max(y - d, 0); d = 0: y;
    d < 0: min(y - d, 0))."""
    out = np.zeros_like(y)
    for di, wi in zip(d, ws):
        if di > 0:
            out += wi * np.maximum(y - di, 0.0)
        elif di < 0:
            out += wi * np.minimum(y - di, 0.0)
        else:
            out += wi * y
    return out


def rate_dependent_pi(u, ts, alpha, beta, rho, tau, n):
    """Thresholds r_j(t) = alpha j + beta |du/dt|, weights rho exp(-tau r_j(t)) (Al Janaideh,
    Su & Rakheja 2008); the first weight p0 on u itself."""
    du = np.abs(np.gradient(u, ts))
    z = np.zeros(n)
    out = np.empty(len(u))
    j = np.arange(1, n + 1)
    for k in range(len(u)):
        r = alpha * j + beta * du[k]
        z = np.maximum(u[k] - r, np.minimum(u[k] + r, z))
        wk = rho * np.exp(-tau * r) * alpha
        out[k] = wk @ z
    return out


# ---------------------------------------------------------------- linear parts


def mode(fn, zeta):
    wn = 2 * math.pi * fn
    return ([wn * wn], [1.0, 2 * zeta * wn, wn * wn])


def lag(tau):
    return ([1.0], [tau, 1.0])


def discretise(tf, ts, method):
    num, den = tf
    b, a, _ = signal.cont2discrete((num, den), ts, method=method)
    return np.ravel(b), np.ravel(a)


def lti(x, tf, ts, method):
    """x through the continuous transfer function tf (unit DC gain), discretised by `method`,
    from rest."""
    b, a = discretise(tf, ts, method)
    return signal.lfilter(b, a, x)


def kelvin_voigt(x, taus, gains, ts):
    """(1 + sum_i g_i / (tau_i s + 1)) x, each cell exact for a piecewise-constant input."""
    y = np.array(x, dtype=float)
    for t, g in zip(taus, gains):
        p = math.exp(-ts / t)
        y += g * signal.lfilter([1 - p], [1, -p], x)
    return y


def log_creep(x, gamma, t0, ts):
    """The logarithmic law as an LTI operator: every change of x creeps on as
    gamma log10(1 + t / t0) times the change (FFT convolution of the increments)."""
    n = len(x)
    dx = np.diff(np.concatenate([[0.0], x]))
    t = np.arange(n) * ts
    step = gamma * np.log10(1.0 + t / t0)
    m = 1 << (2 * n - 1).bit_length()
    c = np.fft.irfft(np.fft.rfft(dx, m) * np.fft.rfft(step, m), m)[:n]
    return x + c

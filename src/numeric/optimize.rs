//! Derivative-free minimisation of small problems: Nelder-Mead in two dimensions, golden-section
//! search on an interval. Both deterministic.
//!
//! ## References
//! - J. A. Nelder, R. Mead, "A simplex method for function minimization", Comput. J.
//!   7(4):308-313, 1965.
//! - J. Kiefer, "Sequential minimax search for a maximum", Proc. AMS 4(3):502-506, 1953.

/// Nelder-Mead on a 2-D function (deterministic).
pub fn nelder_mead(
    f: &dyn Fn(&[f64; 2]) -> f64,
    x0: [f64; 2],
    step: f64,
    iters: usize,
) -> [f64; 2] {
    let mut s = [x0, [x0[0] + step, x0[1]], [x0[0], x0[1] + step]];
    let mut fs = s.map(|p| f(&p));
    for _ in 0..iters {
        let mut idx = [0usize, 1, 2];
        idx.sort_by(|&a, &b| fs[a].total_cmp(&fs[b]));
        s = idx.map(|i| s[i]);
        fs = idx.map(|i| fs[i]);
        let c = [(s[0][0] + s[1][0]) / 2.0, (s[0][1] + s[1][1]) / 2.0];
        let at = |t: f64| [c[0] + t * (s[2][0] - c[0]), c[1] + t * (s[2][1] - c[1])];
        let xr = at(-1.0);
        let fr = f(&xr);
        if fr < fs[0] {
            let xe = at(-2.0);
            let fe = f(&xe);
            if fe < fr {
                s[2] = xe;
                fs[2] = fe;
            } else {
                s[2] = xr;
                fs[2] = fr;
            }
        } else if fr < fs[1] {
            s[2] = xr;
            fs[2] = fr;
        } else {
            let xc = at(0.5);
            let fc = f(&xc);
            if fc < fs[2] {
                s[2] = xc;
                fs[2] = fc;
            } else {
                for i in 1..3 {
                    s[i] = [(s[0][0] + s[i][0]) / 2.0, (s[0][1] + s[i][1]) / 2.0];
                    fs[i] = f(&s[i]);
                }
            }
        }
        if (fs[2] - fs[0]).abs() <= 1e-10 * fs[0].abs().max(1e-300) {
            break;
        }
    }
    let best = (0..3).min_by(|&a, &b| fs[a].total_cmp(&fs[b])).unwrap_or(0);
    s[best]
}

/// Golden-section minimisation of `f` on [a, b].
pub fn golden_section(f: &dyn Fn(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> f64 {
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd {
        c
    } else {
        d
    }
}
